"""Tests of the time-related families (frequency, windowed variance, change rate)."""
