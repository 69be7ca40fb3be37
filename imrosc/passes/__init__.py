"""Lowering passes over the IR: scope resolution, relative grouping, conditions, events."""
