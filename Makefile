# The README's test command is `make test`; .ci/run calls exactly that.
PYTHON ?= python3

.PHONY: test install lint typecheck unit demo

test: install lint typecheck unit

install:
	$(PYTHON) -m pip install --quiet --disable-pip-version-check -e '.[test]'

lint:
	$(PYTHON) -m ruff check .
	$(PYTHON) -m ruff format --check .

typecheck:
	$(PYTHON) -m mypy

unit:
	$(PYTHON) -m pytest

demo:
	$(PYTHON) -m pip install --quiet --disable-pip-version-check . && imrosc demo
