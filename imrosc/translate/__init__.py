"""Translation: bags to program-point samples, following the translator plan (thesis 3.3)."""
