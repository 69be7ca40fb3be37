"""Bags as tasks on a Dask cluster (``imrosc infer --scheduler ADDRESS``).

The client sends the compiled configuration once (one task whose answer every worker
fetches once), then one task per bag: its path and run number. A worker reads the bag,
updates fresh states of every point and sends back the bag's answer: the states (and, for
calibration, the bag's own invariants), never its samples. The client joins the answers of
adjacent bags as they arrive (:class:`~imrosc.fleet.tree.OrderedTree`), with the same exact
merge as ``-j 1``, so the invariants file is byte for byte the one a single process writes.

A bag that cannot be read is answered with its error, as in one process. A task whose worker
dies is run again on another worker by the scheduler (``distributed.scheduler.allowed-failures``,
3 by default); a task that raises is retried :data:`RETRIES` times. A bag that keeps killing
its workers (one too big for their memory) is tried once more alone on the cluster (so that
the bags queued beside it are not blamed), then reported as a bag that could not be read.
"""

from __future__ import annotations

import importlib
import uuid
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from imrosc import __version__
from imrosc.infer.engine import BagJob, BagResult, Merged, Progress, run_bag

from .tree import OrderedTree

RETRIES = 2
"""How many times a bag's task that raised is run again."""
CONNECT_TIMEOUT = 10.0
"""Seconds to reach the scheduler."""
INSTALL = "pip install 'imrosc[fleet]'"
KILLED = "its Dask workers died while reading it, on every try (a bag too big for their memory?)"


class FleetError(Exception):
    """The cluster cannot be used: Dask missing, the scheduler unreachable or lost, workers
    without imrosc. The message is one line."""


def run_remote(template: BagJob, bag: Path, run: int) -> BagResult:
    """A bag's task: the pass's job (scattered once per worker) for this bag."""
    return run_bag(replace(template, bag=bag, run=run))


def _same(job: BagJob) -> BagJob:
    return job


def worker_version() -> str:
    """The imrosc version a worker imports."""
    return __version__


def _distributed() -> Any:
    """The ``distributed`` module (untyped here), or :class:`FleetError` without it."""
    try:
        return importlib.import_module("distributed")
    except ImportError:
        raise FleetError(f"--scheduler needs Dask (dask and distributed): {INSTALL}") from None


def _check_address(distributed: Any, address: str) -> None:
    """Refuse an address Dask cannot parse before a client exists (a failed client prints
    a traceback when it is collected)."""
    try:
        scheme, _ = distributed.comm.parse_address(address)
        distributed.comm.registry.get_backend(scheme)
    except ValueError as error:
        raise FleetError(f"{address}: not a Dask scheduler address: {error}") from None


@dataclass
class Fleet:
    """A connected Dask client, used as the inference engine's bag reducer."""

    client: Any
    """A ``distributed.Client``."""
    address: str
    task: Callable[[BagJob, Path, int], BagResult] = run_remote
    """A bag's task (tests put in one that kills its worker)."""

    @property
    def workers(self) -> int:
        """Workers the scheduler has now."""
        info: dict[str, Any] = self.client.scheduler_info()
        return len(info.get("workers", {}))

    def check_workers(self) -> None:
        """Every worker must import this imrosc (the tasks name its functions)."""
        answers = self.client.run(worker_version, on_error="return")
        for worker, answer in sorted(answers.items()):
            if isinstance(answer, BaseException):
                raise FleetError(
                    f"{self.address}: worker {worker} cannot run imrosc ({answer}); "
                    f"install imrosc {__version__} where the workers run"
                )
            if answer != __version__:
                raise FleetError(
                    f"{self.address}: worker {worker} runs imrosc {answer}, "
                    f"this is imrosc {__version__}"
                )

    def __call__(self, jobs: Sequence[BagJob], progress: Progress | None) -> Merged:
        """Run one pass's jobs (they differ only in bag and run) as one task per bag and
        merge their answers in bag order."""
        as_completed = _distributed().as_completed
        if not jobs:
            return Merged()
        token = uuid.uuid4().hex[:12]
        tree: OrderedTree[Merged] = OrderedTree(len(jobs), Merged.join)

        def take(index: int, result: BagResult) -> None:
            if progress is not None:
                progress(result.bag, result.messages)
            tree.add(index, Merged.of(result))

        try:
            # a task, not scattered data: the scheduler keeps it and computes it again when
            # the workers that held it die
            template = self.client.submit(_same, jobs[0], key=f"imrosc-job-{token}", pure=False)
            futures = [self._submit(template, job, f"{token}-{i}") for i, job in enumerate(jobs)]
            position = {future.key: index for index, future in enumerate(futures)}
            completed = as_completed(futures, loop=self.client.loop)
            del futures  # a bag's answer is forgotten on the cluster once merged here
            doubtful = []
            for future in completed:
                index = position[future.key]
                result = self._answer(future, jobs[index].bag)
                future.release()
                if result is None:
                    doubtful.append(index)
                else:
                    take(index, result)
            # a worker that dies takes the tasks queued on it along: each bag whose workers
            # died is tried once more, alone on the cluster, before it is called bad
            for index in doubtful:
                future = self._submit(template, jobs[index], f"{token}-{index}-alone")
                result = self._answer(future, jobs[index].bag)
                future.release()
                take(index, result or BagResult(jobs[index].bag, error=KILLED))
            template.release()
        except (OSError, TimeoutError) as error:
            raise FleetError(f"{self.address}: lost the Dask scheduler: {error}") from None
        return tree.result()

    def _submit(self, template: Any, job: BagJob, key: str) -> Any:
        return self.client.submit(
            self.task,
            template,
            job.bag.absolute(),  # the workers' own folder may differ from ours
            job.run,
            key=f"imrosc-bag-{key}",
            retries=RETRIES,
            pure=False,
        )

    def _answer(self, future: Any, bag: Path) -> BagResult | None:
        """The bag's answer, with the bag named as the client names it; ``None`` when its
        workers died on every try (``distributed.scheduler.allowed-failures``)."""
        distributed = _distributed()
        try:
            result: BagResult = future.result()
        except distributed.KilledWorker:
            return None
        except distributed.client.FutureCancelledError:
            raise FleetError(f"{self.address}: lost the Dask scheduler") from None
        result.bag = bag
        for unit in result.units:
            unit.bag = bag
        return result


@contextmanager
def connect(address: str, timeout: float | None = None) -> Iterator[Fleet]:
    """A client of the Dask scheduler at ``address``, closed on leaving; :class:`FleetError`
    when Dask is missing, the scheduler cannot be reached or a worker cannot run imrosc."""
    distributed = _distributed()
    _check_address(distributed, address)
    try:
        client = distributed.Client(
            address, timeout=timeout or CONNECT_TIMEOUT, set_as_default=False
        )
    except (OSError, TimeoutError) as error:
        raise FleetError(f"{address}: cannot reach the Dask scheduler: {error}") from None
    try:
        fleet = Fleet(client, address)
        fleet.check_workers()
        yield fleet
    finally:
        client.close()
