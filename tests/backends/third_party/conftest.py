"""``dist/`` is a folder as a site-packages directory holds an installed distribution: the
tests put it on the path; collecting it would import (and so register) its backend."""

collect_ignore = ["dist"]
