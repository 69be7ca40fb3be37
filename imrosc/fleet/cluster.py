"""Bags as tasks on a Dask cluster (``--scheduler ADDRESS`` of ``infer``, ``replay``, ``classify``
and ``stability``).

Before anything is compiled, the catalogue of the bags (each topic's type, its publishers,
the record topics) is read by one task per bag (:meth:`Fleet.note_bags`): each bag's note, a
few KB, goes to the client, which merges the notes in bag order as one process reading the
bags in turn would. The client then sends the compiled configuration once (one task whose
answer every worker fetches once), then one task per bag: its path and run number, each
worker a consecutive share of the bags. A worker reads the bag and updates fresh states of
every point: the bag's answer, which stays on the cluster. The client fetches of each answer
only its summary (messages, errors, the values of its discrete variables, and for calibration
the bag's own invariants); the answers of adjacent bags are joined by join tasks submitted
with the bags (:class:`~imrosc.fleet.tree.OrderedTree` over futures: each share's blocks of
halving size, each a balanced tree, joined left to right, the shares joined as a balanced
tree), the exact merge of ``-j 1`` run on the workers as soon as both answers are computed;
the client fetches the root, the merged states of every bag. The second pass starts as soon
as every summary of the first is in (the conditions it needs come from the discrete values),
while the first pass's last joins still run. Samples never leave
the worker that read them, and the invariants file is byte for byte the one a single process
writes.

Calibration's held-out replays are tasks too: each fold's bags in as many groups as give
every worker one, each fold's document sent once. The replays of ``imrosc replay``,
``classify`` and ``stability`` are one task per bag (:meth:`Fleet.replay_runs`,
:meth:`Fleet.observe_runs`), the document sent once, the answers in bag order.

A bag that cannot be read is answered with its error, as in one process. A task whose worker
dies is run again on another worker by the scheduler (``distributed.scheduler.allowed-failures``,
3 by default); a task that raises is retried :data:`RETRIES` times. A bag that keeps killing
its workers (one too big for their memory) is tried once more alone on the cluster (so that
the bags queued beside it are not blamed), then reported as a bag that could not be read; the
joins above it failed with it, so the pass runs once more with that bag given as failed.
"""

from __future__ import annotations

import importlib
import threading
import uuid
from collections import OrderedDict
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from imrosc import __version__
from imrosc.infer.engine import (
    BagJob,
    BagResult,
    DiscreteValues,
    Early,
    Merged,
    Progress,
    Unit,
    run_bag,
)
from imrosc.progress import bag_done
from imrosc.translate.catalog import BagNote, note_bag

from .tree import OrderedTree, cut

if TYPE_CHECKING:
    from imrosc.calibrate.envelope import Envelopes, FoldDocument
    from imrosc.calibrate.rule import HeldOut, Job
    from imrosc.classify import RunOutcome, RunTask
    from imrosc.replay import RunResult

T = TypeVar("T")

RETRIES = 2
"""How many times a bag's task that raised is run again."""
JOIN_PRIORITY = 1
"""Joins and summaries run before the bags still queued (those have priority 0 and less: a
pass's bag ``i`` has ``-i``, so that a worker reads its share in order)."""
CONNECT_TIMEOUT = 10.0
"""Seconds to reach the scheduler."""
INSTALL = "pip install 'imrosc[fleet]'"
CLUSTER_CONFIG: dict[str, Any] = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "500ms",
}
"""The Dask settings ``docs/fleet.md`` recommends for the scheduler and workers of an imrosc
cluster (as ``DASK_DISTRIBUTED__...`` variables where they start): no statistical profiler
sampling each worker's thread every 10 ms (about 4 % of a busy worker's CPU), and the event
loops' tick monitors, system monitors and the nannies' memory monitors at a second or half a
second instead of 20, 500 and 100 ms (on two cores, a LocalCluster's scheduler and nannies
took 0.07 of a core for them beside the workers)."""
KILLED = "its Dask workers died while reading it, on every try (a bag too big for their memory?)"


class FleetError(Exception):
    """The cluster cannot be used: Dask missing, the scheduler unreachable or lost, workers
    without imrosc. The message is one line."""


def run_remote(template: BagJob, bag: Path, run: int) -> BagResult:
    """The work of a bag's task: the pass's job for this bag."""
    return run_bag(replace(template, bag=bag, run=run))


Task = Callable[[BagJob, Path, int], BagResult]


def _same(job: BagJob) -> BagJob:
    return job


@dataclass(frozen=True)
class _Sealed:
    """A value Dask passes to a task as it is: Dask walks the dicts, lists and tuples of a
    task's arguments in search of futures, which takes seconds on an invariants document
    of thousands of invariants (a client's CPU, before the task is sent)."""

    value: Any


def _unsealed(sealed: _Sealed) -> Any:
    """A task that gives the sealed value (once on the cluster, a future of it)."""
    return sealed.value


def _fold_document(envelopes: Envelopes, units: frozenset[int]) -> dict[str, Any]:
    """A calibration task: a fold's document, learnt from ``units`` (built on the worker
    that replays the fold, from the envelopes sent once)."""
    from imrosc.calibrate.envelope import FoldDocument

    return FoldDocument(envelopes, units).build()


def _answer(task: Task, template: BagJob, bag: Path, run: int, name: Path) -> Merged:
    """A bag's task: its answer, the bag named ``name`` as the client names it."""
    result = task(template, bag, run)
    result.bag = name
    for unit in result.units:
        unit.bag = name
    return Merged.of(result)


Summary = tuple[int, list[Unit], str | None, dict[str, DiscreteValues]]
"""What the client fetches of a bag's answer: its messages, calibration units, error and the
values of its points' discrete variables (by point key)."""


def _summary(answer: Merged) -> Summary:
    """A bag's :data:`Summary`."""
    discrete = {
        key: state.discrete
        for key, state in (answer.states or {}).items()
        if state.discrete is not None
    }
    return answer.messages, answer.units, next(iter(answer.failed.values()), None), discrete


def _join(left: Merged, right: Merged) -> Merged:
    """A join task: adjacent answers merged, their units left out (the client has them)."""
    for point in (left.states or {}).values():
        for state in point.states:
            freeze = getattr(state, "freeze", None)  # no samples come again: drop caches
            if freeze is not None:
                freeze()
    joined = Merged(left.states, dict(left.failed), left.messages, list(left.empty))
    return joined.join(Merged(right.states, right.failed, right.messages, right.empty))


def _failed(bag: Path, error: str) -> Merged:
    return Merged(failed={bag: error})


def _failed_run(bag: Path) -> dict[str, Any]:
    """The run in ``replay``'s report of a bag whose workers died reading it."""
    return {
        "bag": str(bag),
        "start": None,
        "end": None,
        "messages": 0,
        "skipped": 0,
        "error": KILLED,
        "warnings": [],
        "checked": {},
        "unchecked": [],
        "violations": 0,
        "alarms": [],
        "episodes": [],
        "plots": {"polygons": [], "frequencies": []},
    }


_replayers = threading.local()
"""Per worker thread and kind of run, the engine of the last document it replayed."""
REPLAYERS = 1
"""Engines a worker thread keeps per kind of run: the stages send one document at a time,
and an engine holds tens of MB (its polygons' tables)."""


def _replay(
    document: Mapping[str, Any],
    bags: list[tuple[Path, list[tuple[float, float] | None], Path]],
    fold: int,
) -> list[HeldOut]:
    """A calibration task: some bags' held-out units of a fold replayed, each bag
    ``(path, spans, name)``, with the fold's engine built for the task and dropped after
    (a worker's tasks are consecutive slices of the folds: :func:`shares`)."""
    from imrosc.calibrate.rule import held_out, held_out_replayer

    replayer = held_out_replayer(document)
    found = []
    for bag, spans, name in bags:
        units = held_out(replayer, bag, spans, fold)
        for unit in units:
            unit.bag = str(name)
        found += units
    return found


Slice = tuple[int, int, int]
"""A fold's bags ``first:stop``, as ``(fold, first, stop)``."""


def shares(sizes: Sequence[int], parts: int) -> list[list[Slice]]:
    """The folds' bags (``sizes`` of them per fold) in ``parts`` consecutive shares of as
    many bags as can be (the first ones a bag more), each share the slices of the folds it
    spans: a worker that replays a share builds the engines of those folds only (a fold's
    engine is built by at most the workers that share it), and the shares' bags differ by
    one at most.

    >>> shares([4, 4, 4], 2)
    [[(0, 0, 4), (1, 0, 2)], [(1, 2, 4), (2, 0, 4)]]
    """
    total = sum(sizes)
    parts = max(1, min(parts, total))
    found: list[list[Slice]] = [[] for _ in range(parts)]
    share, taken = 0, 0  # the share being filled, the bags it has
    for fold, size in enumerate(sizes):
        first = 0
        while first < size:
            room = total // parts + (share < total % parts) - taken
            stop = min(size, first + room)
            found[share].append((fold, first, stop))
            taken += stop - first
            first = stop
            if taken == total // parts + (share < total % parts):
                share, taken = share + 1, 0
    return found


def _cached(kind: str, key: str, build: Callable[[], T]) -> T:
    """This worker thread's engine of kind ``kind`` for the document ``key`` (the last
    :data:`REPLAYERS` kept)."""
    cache: OrderedDict[str, Any] | None = getattr(_replayers, kind, None)
    if cache is None:
        cache = OrderedDict()
        setattr(_replayers, kind, cache)
    found: T | None = cache.get(key)
    if found is None:
        found = cache[key] = build()
        while len(cache) > REPLAYERS:
            cache.popitem(last=False)
    return found


def _renamed(text: str | None, bag: Path, name: Path) -> str | None:
    """A message about a bag read at ``bag``, naming it ``name`` as the client does."""
    if text is None or bag == name:
        return text
    return text.replace(str(bag), str(name))


def _replay_run(
    document: Mapping[str, Any], key: str, bag: Path, name: Path, plots: bool
) -> tuple[RunResult, dict[str, Any]]:
    """A ``replay`` task: one bag replayed (the document's engine built once per thread)."""
    from imrosc.replay import RunReplayer

    replay = _cached("runs", key, lambda: RunReplayer(document, plots))
    result, run = replay(bag)
    result.bag = name
    run["bag"] = str(name)
    result.error = run["error"] = _renamed(result.error, bag, name)
    return result, run


def _observe_run(
    document: Mapping[str, Any],
    key: str,
    bag: Path,
    task: RunTask,
    name: Path,
    collect: bool = False,
) -> RunOutcome:
    """A ``classify`` or ``stability`` task: one run replayed and observed (the document's
    engine built once per thread); ``collect``: its samples too, for learnt detectors."""
    from imrosc.classify import observe, replayer_of

    kind = "samplers" if collect else "observers"
    replayer, sampler = _cached(kind, key, lambda: replayer_of(document, collect))
    outcome = observe(replayer, (bag, task[1]), sampler)
    outcome.bag = name
    outcome.error = _renamed(outcome.error, bag, name)
    outcome.onset_problem = _renamed(outcome.onset_problem, bag, name)
    outcome.warnings = [_renamed(text, bag, name) or text for text in outcome.warnings]
    return outcome


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
    task: Task = run_remote
    """A bag's task (tests put in one that kills its worker)."""
    observe: Callable[..., RunOutcome] = _observe_run
    """A run's task in ``classify`` and ``stability`` (tests put in one that kills its
    worker)."""

    @property
    def workers(self) -> int:
        """Workers the scheduler has now."""
        info: dict[str, Any] = self.client.scheduler_info()
        return len(info.get("workers", {}))

    def check_workers(self) -> None:
        """The scheduler and every worker must import this imrosc (the tasks name its
        functions)."""
        try:
            answer = self.client.run_on_scheduler(worker_version)
        except Exception as error:  # what the scheduler failed to load, whatever it was
            raise FleetError(
                f"{self.address}: the scheduler cannot run imrosc ({error}); "
                f"install imrosc {__version__} where it runs"
            ) from None
        if answer != __version__:
            raise FleetError(
                f"{self.address}: the scheduler runs imrosc {answer}, this is imrosc {__version__}"
            )
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
        merge their answers in bag order on the cluster."""
        return self.begin(jobs, progress).result()

    def begin(self, jobs: Sequence[BagJob], progress: Progress | None) -> _Pass:
        """Start a pass: its bags' tasks submitted (:class:`~imrosc.infer.engine.Staged`)."""
        return _Pass(self, list(jobs), progress)

    @contextmanager
    def _lost(self) -> Iterator[None]:
        """The scheduler's loss as a :class:`FleetError`."""
        distributed = _distributed()
        try:
            yield
        except distributed.client.FutureCancelledError:
            raise FleetError(f"{self.address}: lost the Dask scheduler") from None
        except (OSError, TimeoutError) as error:
            raise FleetError(f"{self.address}: lost the Dask scheduler: {error}") from None
        except RuntimeError as error:
            if "deserialization of the task graph" not in str(error):
                raise
            raise FleetError(
                f"{self.address}: the scheduler cannot load imrosc's tasks: it runs another "
                f"imrosc than this {__version__}"
            ) from None

    def note_bags(self, bags: Sequence[Path]) -> list[BagNote]:
        """The catalogue's pre-pass: each bag's note (:func:`~imrosc.translate.catalog.note_bag`:
        its topics' types, publishers, record topics) read by a task of its own, the notes in
        bag order (the client merges them as one process reads the bags in turn). A bag whose
        workers died on every try is a bag that cannot be read."""
        if not bags:
            return []
        distributed = _distributed()
        client = self.client
        token = uuid.uuid4().hex[:12]
        futures = {
            client.submit(
                note_bag,
                bag.absolute(),  # the workers' own folder may differ from ours
                bag,
                key=f"imrosc-note-{token}-{index}",
                retries=RETRIES,
                pure=False,
            ): index
            for index, bag in enumerate(bags)
        }
        notes: list[BagNote | None] = [None] * len(bags)
        try:
            for future in distributed.as_completed(list(futures), loop=client.loop):
                index = futures.pop(future)
                try:
                    notes[index] = future.result()
                except distributed.KilledWorker:
                    notes[index] = BagNote(bags[index], error=KILLED)
                finally:
                    future.release()
        except distributed.client.FutureCancelledError:
            raise FleetError(f"{self.address}: lost the Dask scheduler") from None
        except (OSError, TimeoutError) as error:
            raise FleetError(f"{self.address}: lost the Dask scheduler: {error}") from None
        finally:
            for future in futures:
                future.release()
        return [note for note in notes if note is not None]

    def replay_held_out(self, jobs: Sequence[Job]) -> list[list[HeldOut]]:
        """Calibration's held-out replays: the folds' bags cut in one consecutive share per
        worker (:func:`shares`), each share's slices of folds a task suggested to its
        worker; each fold's document sent once and released, with the answers, as soon as
        its tasks are done. The answers in the order of the folds and their bags."""
        client = self.client
        distributed = _distributed()
        token = uuid.uuid4().hex[:12]
        folds = [
            [(bag.absolute(), spans, bag) for bag, spans in bags.items()] for _, bags, _ in jobs
        ]
        workers = sorted(client.scheduler_info().get("workers", {})) or [None]
        found: list[list[list[HeldOut]]] = [[] for _ in jobs]
        learnt: dict[int, Any] = {}
        tasks: dict[Any, tuple[int, int]] = {}
        left = [0] * len(jobs)
        sent: dict[int, Any] = {}
        """The futures of the folds' envelopes, by ``id``: sent once."""
        try:
            order = 0
            cut = shares([len(bags) for bags in folds], len(workers))
            for worker, share in zip(workers, cut, strict=False):  # fewer bags than workers: shares
                where = {} if worker is None else {"workers": [worker], "allow_other_workers": True}
                for fold, first, stop in share:
                    if fold not in learnt:
                        # a task, not scattered data: computed again if its workers die
                        learnt[fold] = self._learnt(
                            jobs[fold][0], sent, f"imrosc-fold-{token}-{fold}", where
                        )
                    task = client.submit(
                        _replay,
                        learnt[fold],
                        folds[fold][first:stop],
                        jobs[fold][2],
                        key=f"imrosc-replay-{token}-{fold}-{first}",
                        retries=RETRIES,
                        priority=-order,  # a worker's slices in the folds' order
                        **where,
                    )
                    order += 1
                    tasks[task] = (fold, len(found[fold]))
                    found[fold].append([])
                    left[fold] += 1
            for future in sent.values():
                future.release()  # kept by the scheduler until the folds' documents are built
            sent.clear()
            for task in distributed.as_completed(list(tasks), loop=client.loop):
                fold, index = tasks.pop(task)
                found[fold][index] = task.result()
                task.release()
                left[fold] -= 1
                if not left[fold]:
                    learnt.pop(fold).release()
        except distributed.KilledWorker as killed:
            raise FleetError(
                f"{self.address}: the Dask workers died replaying held-out bags ({killed})"
            ) from None
        except (OSError, TimeoutError) as error:
            raise FleetError(f"{self.address}: lost the Dask scheduler: {error}") from None
        finally:
            for future in [*tasks, *learnt.values(), *sent.values()]:
                future.release()
        return [[unit for part in fold for unit in part] for fold in found]

    def _learnt(
        self, learnt: Mapping[str, Any] | FoldDocument, sent: dict[int, Any], key: str, where: Any
    ) -> Any:
        """The future of a fold's document: built by a task from its envelopes (sent once,
        their future kept in ``sent``), or sent as it is."""
        from imrosc.calibrate.envelope import FoldDocument

        client = self.client
        if not isinstance(learnt, FoldDocument):
            return client.submit(_unsealed, _Sealed(learnt), key=key, **where)
        envelopes = sent.get(id(learnt.envelopes))
        if envelopes is None:
            envelopes = sent[id(learnt.envelopes)] = client.submit(
                _unsealed, _Sealed(learnt.envelopes), key=f"{key}-envelopes", **where
            )
        return client.submit(_fold_document, envelopes, learnt.units, key=key, **where)

    def replay_runs(
        self,
        document: Mapping[str, Any],
        bags: list[Path],
        plots: bool,
        progress: Progress | None,
    ) -> list[tuple[RunResult, dict[str, Any]]]:
        """``imrosc replay``: one task per bag (the document sent once), the runs in bag
        order; ``progress`` hears of each bag as it completes."""
        from imrosc.replay import RunResult

        def killed(bag: Path) -> tuple[RunResult, dict[str, Any]]:
            result = RunResult(bag)
            result.error = KILLED
            return result, _failed_run(bag)

        return self._each_bag(
            document,
            bags,
            lambda learnt, key, bag: (_replay_run, learnt, key, bag.absolute(), bag, plots),
            killed,
            lambda answer: (answer[0].messages, answer[0].error),
            progress,
        )

    def observe_runs(
        self,
        document: Mapping[str, Any],
        tasks: list[RunTask],
        progress: Progress | None,
        collect: bool = False,
    ) -> list[RunOutcome]:
        """``imrosc classify`` and ``imrosc stability``: one task per run (the document
        sent once), the outcomes in the runs' order; ``progress`` hears of each run as it
        completes; ``collect``: the runs' samples too (learnt detectors)."""
        from imrosc.classify import RunOutcome

        specs = dict(tasks)
        return self._each_bag(
            document,
            [bag for bag, _ in tasks],
            lambda learnt, key, bag: (
                self.observe,
                learnt,
                key,
                bag.absolute(),
                (bag, specs[bag]),
                bag,
                collect,
            ),
            lambda bag: RunOutcome(bag, KILLED),
            lambda outcome: (outcome.messages, outcome.error),
            progress,
        )

    def _each_bag(
        self,
        document: Mapping[str, Any],
        bags: list[Path],
        task: Callable[[Any, str, Path], tuple[Any, ...]],
        killed: Callable[[Path], T],
        messages: Callable[[T], tuple[int, str | None]],
        progress: Progress | None,
    ) -> list[T]:
        """One task per bag, ``task(document's future, its key, bag)`` (the function and its
        arguments), the document sent once to every worker; the answers in bag order, a bag
        whose workers died on every try answered by ``killed``; ``progress`` hears of each
        bag's ``messages(answer)`` (its messages and error)."""
        if not bags:
            return []
        distributed = _distributed()
        client = self.client
        key = f"imrosc-document-{uuid.uuid4().hex[:12]}"
        try:
            learnt = client.submit(_unsealed, _Sealed(document), key=key)
            client.replicate([learnt])
            futures = {
                client.submit(*task(learnt, key, bag), key=f"{key}-{index}", retries=RETRIES): index
                for index, bag in enumerate(bags)
            }
            answers: list[T | None] = [None] * len(bags)
            for future in distributed.as_completed(list(futures), loop=client.loop):
                index = futures.pop(future)
                try:
                    answer: T = future.result()
                except distributed.KilledWorker:
                    answer = killed(bags[index])
                answers[index] = answer
                future.release()
                bag_done(progress, bags[index], *messages(answer))
            learnt.release()
        except distributed.client.FutureCancelledError:
            raise FleetError(f"{self.address}: lost the Dask scheduler") from None
        except (OSError, TimeoutError) as error:
            raise FleetError(f"{self.address}: lost the Dask scheduler: {error}") from None
        return [answer for answer in answers if answer is not None]

    def _submit(self, template: Any, job: BagJob, key: str, worker: str | None = None) -> Any:
        """A bag's task, suggested to ``worker``: a worker runs its bags in order (tasks
        submitted together tie on Dask's priority and would run in any order)."""
        where = {} if worker is None else {"workers": [worker], "allow_other_workers": True}
        return self.client.submit(
            _answer,
            self.task,
            template,
            job.bag.absolute(),  # the workers' own folder may differ from ours
            job.run,
            job.bag,
            key=f"imrosc-bag-{key}",
            retries=RETRIES,
            pure=False,
            priority=-job.run,
            **where,
        )

    def _summary(self, future: Any) -> Summary | None:
        """A bag's summary; ``None`` when its workers died on every try
        (``distributed.scheduler.allowed-failures``)."""
        try:
            found: Summary = future.result()
        except _distributed().KilledWorker:
            return None
        finally:
            future.release()
        return found


class _Pass:
    """A pass on the cluster (:class:`~imrosc.infer.engine.Staged`): its bags' tasks submitted
    when made, each worker a consecutive share of the bags, with the joins of adjacent answers
    (the whole tree: a join runs as soon as its answers are computed); :meth:`early` collects
    each bag's summary as it completes (its messages, error, calibration units and discrete
    values); :meth:`result` fetches the root of the joins, the merged states of every bag."""

    def __init__(
        self,
        fleet: Fleet,
        jobs: list[BagJob],
        progress: Progress | None,
        bad: set[int] | None = None,
    ) -> None:
        self.fleet = fleet
        self.jobs = jobs
        self.progress = progress
        self.retried = bad is not None
        """Whether this is the pass's second try (:meth:`result`)."""
        self.bad: set[int] = set(bad or ())
        """The bags whose workers die reading them (given as failed bags without a try)."""
        self._early: Early | None = None
        self._units: list[list[Unit]] = [[] for _ in jobs]
        self._root: Any = None
        """The future of the root of the joins."""
        self._template: Any = None
        self._token = ""
        """The keys' token of this try's tasks."""
        self._summaries: dict[Any, int] = {}
        if jobs:
            with fleet._lost():
                self._submit()

    def _submit(self) -> None:
        client, jobs = self.fleet.client, self.jobs
        token = self._token = uuid.uuid4().hex[:12]

        def join(left: Any, right: Any) -> Any:
            key = f"imrosc-join-{uuid.uuid4().hex}"
            # before the bags still queued (Dask runs what was submitted first, first): the
            # answers waiting for their neighbour stay few
            return client.submit(_join, left, right, key=key, priority=JOIN_PRIORITY)

        # a task, not scattered data: the scheduler keeps it and computes it again when the
        # workers that held it die
        self._template = client.submit(_same, jobs[0], key=f"imrosc-job-{token}", pure=False)
        client.replicate([self._template])  # the bags' tasks then go to any worker
        # each worker reads a consecutive share of the bags, in order (any other worker takes
        # a bag if it is free or the worker is lost): the joins inside a share find both
        # answers on its worker, and only the shares' joins move states between workers
        workers = sorted(client.scheduler_info().get("workers", {})) or [None]
        sizes = cut(len(jobs), len(workers))
        where = [w for w, size in zip(workers, sizes, strict=False) for _ in range(size)]
        answers = [
            self._killed(i) if i in self.bad else self._bag(job, f"{token}-{i}", where[i])
            for i, job in enumerate(jobs)
        ]
        self._summaries = {
            client.submit(
                _summary, answer, key=f"imrosc-summary-{token}-{i}", priority=JOIN_PRIORITY
            ): i
            for i, answer in enumerate(answers)
        }
        # the whole tree at once: a join runs as soon as its two answers are computed,
        # without waiting for the client to hear of them
        tree: OrderedTree[Any] = OrderedTree(len(jobs), join, sizes)
        for index, answer in enumerate(answers):
            tree.add(index, answer)
        self._root = tree.result()

    def _killed(self, index: int) -> Any:
        return self.fleet.client.submit(_failed, self.jobs[index].bag, KILLED, pure=False)

    def _bag(self, job: BagJob, key: str, worker: str | None = None) -> Any:
        return self.fleet._submit(self._template, job, key, worker)

    def early(self) -> Early:
        """Each bag's summary as it completes; once all are in, the discrete values merged
        over the bags and the failed bags."""
        if self._early is not None:
            return self._early
        early = Early()
        if not self.jobs:
            self._early = early
            return early
        distributed = _distributed()
        client = self.fleet.client

        def take(index: int, got: Summary) -> None:
            messages, self._units[index], error, discrete = got
            if error is not None:
                early.failed.add(self.jobs[index].bag)
            for key, values in discrete.items():
                mine = early.discrete.get(key)
                if mine is None:
                    early.discrete[key] = values
                else:
                    mine.merge(values)
            bag_done(self.progress, self.jobs[index].bag, messages, error)

        with self.fleet._lost():
            doubtful = []
            for summary in distributed.as_completed(list(self._summaries), loop=client.loop):
                index = self._summaries.pop(summary)
                got = self.fleet._summary(summary)
                if got is None:
                    doubtful.append(index)
                    continue
                take(index, got)
            # a worker that dies takes the tasks queued on it along: each bag whose workers
            # died is tried once more, alone on the cluster, before it is called bad (the
            # joins above its answer failed with it: :meth:`result` runs the pass again)
            for index in doubtful:
                answer = self._bag(self.jobs[index], f"{self._token}-{index}-alone")
                got = self.fleet._summary(client.submit(_summary, answer, pure=False))
                answer.release()
                if got is None:
                    self.bad.add(index)
                    got = (0, [], KILLED, {})
                take(index, got)
        # the points' order, as in the merged states
        order = {spec.key: i for i, spec in enumerate(self.jobs[0].specs)}
        early.discrete = dict(sorted(early.discrete.items(), key=lambda kv: order[kv[0]]))
        self._early = early
        return early

    def result(self) -> Merged:
        """The root of the joins: every bag's states merged in bag order, and their units.
        When a bag's workers died on every try (the joins above it failed with it), the pass
        runs once more, the bags that kill workers given as failed."""
        if not self.jobs:
            return Merged()
        self.early()
        distributed = _distributed()
        with self.fleet._lost():
            try:
                merged: Merged = self._root.result()
            except distributed.KilledWorker:
                if self.retried:
                    raise FleetError(f"{self.fleet.address}: the Dask workers keep dying") from None
                again = _Pass(self.fleet, self.jobs, None, self.bad)
                merged = again.result()
                self._units = again._units
            finally:
                self._root.release()
                self._template.release()
        merged.units = [unit for found in self._units for unit in found]
        return merged


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
