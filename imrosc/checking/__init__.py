"""Offline checking at decode speed: a bag's messages checked as column chunks.

``imrosc replay`` (and ``classify`` and ``stability``, which replay every run) reads a bag in
chunks of messages, decodes each topic's messages of a chunk at once into a float64 matrix
(:mod:`.decode`, the translator's :class:`~imrosc.translate.rawdecode.RawDecoder`), and
checks each publish point over its chunk of samples (:mod:`.points`): the samples paired
with their input topics, the conditions, the value checks, the time windows with their
silence timers, the alarms. What is not vectorised goes to the runtime engine message by
message, as before (:mod:`.run`). The violations and alarms come out exactly as the
per-message engine gives them, in its order (a randomised test over every family holds the
two paths equal).
"""
