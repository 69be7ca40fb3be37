"""The Dask cluster the fleet tests share: a scheduler and two single-threaded worker
processes on loopback."""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from typing import Any

import pytest

distributed: Any = importlib.import_module("distributed")  # the [test] extra installs Dask
dask: Any = importlib.import_module("dask")


@pytest.fixture(scope="session")
def address() -> Iterator[str]:
    """The scheduler's address; a task whose worker dies is run again once (a second death
    is a ``KilledWorker``)."""
    with (
        dask.config.set({"distributed.scheduler.allowed-failures": 1}),
        distributed.LocalCluster(
            n_workers=2,
            processes=True,
            threads_per_worker=1,
            host="127.0.0.1",
            scheduler_port=0,
            dashboard_address=":0",
            silence_logs=50,
        ) as local,
    ):
        yield local.scheduler_address


@pytest.fixture(scope="session")
def client(address: str) -> Iterator[Any]:
    with distributed.Client(address, set_as_default=False) as connected:
        yield connected
