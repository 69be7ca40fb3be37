"""Backends as installed packages ship them; none is collected: importing one registers it.

``site/`` is a folder as a site-packages directory holds an installed distribution (the tests
put it on the path); ``toy.py`` and ``silent.py`` are found through entry points the tests
declare."""

collect_ignore = ["site", "toy.py", "silent.py"]
