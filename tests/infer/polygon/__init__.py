"""Tests of the polygon family (exact convex hulls of variable pairs)."""
