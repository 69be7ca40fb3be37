"""A module named as a backend that registers nothing."""
