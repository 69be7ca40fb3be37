"""Inference: program-point samples to invariants (thesis chapter 3)."""
