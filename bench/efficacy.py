"""Detection efficacy: alarms on runs the invariants were not learnt from, with known faults.

    python bench/efficacy.py [--only alfa,crazyflie,sim] [--folds 5|session] [-j N] [--keep DIR]
    python bench/efficacy.py --alfa-test DIR [-j N]

Every part learns with ``imrosc.detect.run_detect`` and replays with ``imrosc.replay.Replayer``
under the alarm rule the invariants document carries; nothing here tunes anything. An alarm's
time is in bag-clock seconds; a fault's onset is the bag time it starts at.

Scoring, per run (:func:`outcome`, :func:`score`):

* **detected**: the run's *first* alarm is at or after the fault's onset (an alarm before the
  onset is a false alarm, and the run is then not counted as detected, whatever follows);
* **delay**: first alarm at or after the onset minus the onset (printed for every run that
  alarmed after the onset; the mean and max are over detected runs only);
* **false-alarm run**: a fault run with an alarm before its onset, or a nominal run with any
  alarm;
* **recall**: detected fault runs / fault runs;
* **precision**: detected runs / runs with any alarm (nominal runs that alarmed count in the
  denominator), "n/a" when no run alarmed.

Parts:

* **alfa**: the 21 labelled flights of ``../shared/data/real/alfa`` (``onsets.json``) in K
  folds by recording session (flights sharing the date-time stamp of their name stay in one
  fold; sessions go, largest first, to the fold with the fewest flights; ``--folds session``:
  one fold per session, leave one session out). Each fold learns
  from the other folds, in two stages, then replays its own flights whole with both
  documents:

  1. *inferred*: ``run_detect`` on the other folds' no-failure flights whole and their fault
     flights up to the onset (copies of the bags holding the messages before the onset only,
     every connection kept);
  2. *classified*: ``imrosc.classify.run_check`` (the Python API of ``imrosc classify``) on a
     configuration whose <detect> lists the same bags and whose <check> has them as
     <success> runs and the other folds' fault flights, whole, as
     ``<fail onset_topic="/failure_status">`` runs: the inferred document refined (the
     invariants ``<check select>`` keeps: imrosc's default, the set whose union detects the
     most failed runs minus its expected false alarms, or with ``--select fscore`` those whose
     F-score reaches the threshold; the alarm rule set again for the kept ones from
     calibration's held-out traces). With ``<check detector="logistic">`` (imrosc's
     default; ``--detector none`` for the invariants alone) classification also learns a
     fault detector per point, and keeps the cover, the detector or both, whichever failed
     runs held out of the choice show worth the most (docs/families/detector.md). The
     <success> runs are the <detect> runs: run_check
     scores them from what each broke when calibration held it out (cross-validated false
     positives, blocked by recording time), not from a replay against what they taught. The
     fault flights' pre-onset parts are in-sample (their copies trained the invariants).
     Should a file keep no held-out replay of them, run_check warns ``success-in-detect``,
     printed as expected. ``cross_validate`` is not used: it would infer K more times per
     fold for what the held-out traces already say.

  Printed: per fold the invariants and alarm rule of both documents and the classification's
  warnings; each flight under both (alarms, first alarm, delay, verdict), and what raised
  each false alarm's first alarm (point, rule, invariant); then per fault
  class and overall, under both, the runs, detected, recall, false-alarm runs, precision,
  mean and max delay. The target's verdict is the classified monitor's (the pipeline's
  product: infer, classify, monitor), the inferred figures beside it. Reference to beat: RLS
  on ALFA, precision 0.88, recall 0.88, mean delay 2.02 s (Keipour, Mousaei, Scherer, ICRA
  2019).
* **--alfa-test DIR**: flights the development ones never saw (laid out like
  ``../shared/data/real/alfa``: the bags under DIR, an ``onsets.json`` naming them relative to
  DIR). Both monitors are learnt once, as a fold's are, from all 21 development flights, and
  DIR's flights replayed whole with them; printed as the k-fold part prints its flights and
  scores, against the same target. With it, only this part runs.
* **crazyflie**: the scope of ``examples/crazyflie.xml``. Learn on ``sine_1.bag`` alone, replay
  ``sine_2.bag`` (alarms, violations, first alarm) and ``sine_1.bag``; learn on both, replay both
  and six faulty copies of ``sine_2`` the bench writes itself, each fault starting at 60 % of
  the bag's duration (:data:`FAULTS`): detected, delay, alarms before the onset.
* **sim**: the simulated landing system (``imrosc.sim``, ``landing_sim.xml`` of ``imrosc demo``),
  in the same two stages: infer on nominal runs; classify with those nominal runs as
  <success> and one run of each fault scenario from other seeds than the replayed ones as
  ``<fail onset="10.0">`` (the nominal runs scored from their held-out traces); replay two
  held-out nominal runs and one held-out run of each fault scenario (the fault from 10 s
  on) with both: detected, delay, alarms before the fault. The verdict is the classified monitor's.

Targets (issue 17), each printed MET or NOT MET from the measured figures: ALFA k-fold recall
>= 0.85 with false alarms on <= 10 % of flights and mean delay <= 2.5 s; Crazyflie sine_1 ->
sine_2 without an alarm; all six injected faults detected within 1.5 s of the onset with no
alarm before it; the training bags replayed without an alarm; every simulated scenario
detected.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import os
import re
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple
from xml.sax.saxutils import escape

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from lxml import etree
from rosbags.rosbag1 import Reader, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from imrosc.classify import run_check  # noqa: E402
from imrosc.detect import run_detect  # noqa: E402
from imrosc.diagnostics import Diagnostic, has_errors, render_text  # noqa: E402
from imrosc.invariants import dumps  # noqa: E402
from imrosc.replay import Replayer, RunResult  # noqa: E402
from imrosc.runtime.alarms import Alarm  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "real"
ALFA = DATA / "alfa"
CRAZYFLIE = DATA / "crazyflie"
SECOND = 1_000_000_000
PARTS = ("alfa", "crazyflie", "sim")

ALFA_SCOPE = '<scope>\n    <publish id="m">/alfa/merged</publish>\n  </scope>'
REFERENCE = (
    "RLS on ALFA: precision 0.88, recall 0.88, mean delay 2.02 s (Keipour et al., ICRA 2019)"
)
ALFA_RECALL, ALFA_FALSE, ALFA_DELAY = 0.85, 0.10, 2.5
ALFA_LABEL = "/failure_status"
"""ALFA's label topic: its first non-zero message is the fault's onset."""
FAULT_DELAY = 1.5
FAULT_AT = 0.6
"""The injected faults start at this fraction of sine_2's duration."""
SIM_NOMINAL, SIM_HELD_OUT, SIM_START = 6, 2, 10.0
TARGETS = (
    f"ALFA k-fold (classified): recall >= {ALFA_RECALL}, false alarms on <= "
    f"{ALFA_FALSE:.0%} of flights, mean delay <= {ALFA_DELAY} s",
    "Crazyflie: learnt on sine_1, sine_2 replays with 0 alarms",
    f"Crazyflie: all six injected faults detected within {FAULT_DELAY} s of the onset, "
    "0 alarms before it",
    "Crazyflie: the training bags replay with 0 alarms",
    "Simulated landing system (classified): every fault scenario detected",
    f"ALFA flights of --alfa-test, learnt from every development flight (classified): "
    f"recall >= {ALFA_RECALL}, false alarms on <= {ALFA_FALSE:.0%} of flights, mean delay "
    f"<= {ALFA_DELAY} s",
)


# --- bags as lists of messages -------------------------------------------------------------


@dataclass(frozen=True)
class Topic:
    """A ROS 1 connection as written: topic, type, definition, md5sum, callerid, latching."""

    topic: str
    msgtype: str
    msgdef: str
    md5sum: str
    callerid: str | None = None
    latching: int | None = None


@dataclass(frozen=True)
class Message:
    """One message of a bag: its connection, bag time (ns) and serialized bytes."""

    topic: Topic
    time: int
    raw: bytes


class Bag(NamedTuple):
    """A ROS 1 bag read whole: its connections, messages in time order, start and end (ns)."""

    topics: list[Topic]
    messages: list[Message]
    start: int
    end: int


def read_bag(path: Path) -> Bag:
    """Every connection and message of a ROS 1 bag."""
    with Reader(path) as reader:
        topics = {
            c.id: Topic(
                c.topic,
                c.msgtype,
                c.msgdef.data,
                c.digest,
                getattr(c.ext, "callerid", None),
                getattr(c.ext, "latching", None),
            )
            for c in reader.connections
        }
        messages = [Message(topics[c.id], stamp, bytes(raw)) for c, stamp, raw in reader.messages()]
        return Bag(list(topics.values()), messages, reader.start_time, reader.end_time)


def write_bag(path: Path, messages: Iterable[Message], topics: Sequence[Topic] = ()) -> Path:
    """Write a ROS 1 bag: the ``topics`` given (even without messages), then those of the
    messages, each with its own definition and callerid; messages in time order."""
    ordered = sorted(messages, key=lambda m: m.time)
    path.parent.mkdir(parents=True, exist_ok=True)
    with Writer(path) as writer:
        connections = {}
        for topic in [*topics, *(m.topic for m in ordered)]:
            if topic not in connections:
                connections[topic] = writer.add_connection(
                    topic.topic,
                    topic.msgtype,
                    msgdef=topic.msgdef,
                    md5sum=topic.md5sum,
                    callerid=topic.callerid,
                    latching=topic.latching,
                )
        for message in ordered:
            writer.write(connections[message.topic], message.time, message.raw)
    return path


def crop(bag: Path, onset: int, out: Path) -> Path:
    """A copy of ``bag`` holding the messages before ``onset`` (ns) only, every connection."""
    read = read_bag(bag)
    return write_bag(out, [m for m in read.messages if m.time < onset], read.topics)


@functools.cache
def _typestore(msgtype: str, msgdef: str) -> Typestore:
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(msgdef, msgtype))
    return store


def decode(message: Message) -> Any:
    """The message's value, decoded with the definition its bag holds."""
    topic = message.topic
    return _typestore(topic.msgtype, topic.msgdef).deserialize_ros1(message.raw, topic.msgtype)


def encode(message: Message, value: Any) -> Message:
    """The message carrying ``value`` instead (same connection and time)."""
    topic = message.topic
    store = _typestore(topic.msgtype, topic.msgdef)
    return dataclasses.replace(message, raw=bytes(store.serialize_ros1(value, topic.msgtype)))


# --- injected faults -----------------------------------------------------------------------

IMU, POS, RPY, RANGES = "/cf1/imu", "/cf1/log_pos", "/cf1/log_rpy", "/cf1/log_ranges"
JUMP = 0.5
"""Metres added to log_pos's x (its first value) by the position jump."""
ACCEL_SCALE = 1.5
INTRUDER = "/crazyflie_server_2"
Inject = Callable[[list[Message], int], list[Message]]


def _changed(
    messages: list[Message], onset: int, topic: str, change: Callable[[Any], Any]
) -> list[Message]:
    """The messages with ``change`` applied to the values of ``topic``'s from the onset on."""
    return [
        encode(m, change(decode(m))) if m.topic.topic == topic and m.time >= onset else m
        for m in messages
    ]


def slowed_topic(messages: list[Message], onset: int) -> list[Message]:
    """/cf1/imu at a third of its rate from the onset on (every third message kept)."""
    out, seen = [], 0
    for m in messages:
        if m.topic.topic == IMU and m.time >= onset:
            seen += 1
            if seen % 3 != 1:
                continue
        out.append(m)
    return out


def dead_topic(messages: list[Message], onset: int) -> list[Message]:
    """/cf1/log_ranges stops at the onset."""
    return [m for m in messages if not (m.topic.topic == RANGES and m.time >= onset)]


def frozen_sensor(messages: list[Message], onset: int) -> list[Message]:
    """/cf1/log_rpy repeats the values of its last message before the onset (headers go on)."""
    before = [m for m in messages if m.topic.topic == RPY and m.time < onset]
    if not before:
        return list(messages)
    last = decode(before[-1])
    return _changed(messages, onset, RPY, lambda v: dataclasses.replace(last, header=v.header))


def position_jump(messages: list[Message], onset: int) -> list[Message]:
    """/cf1/log_pos's x (its first value) JUMP metres further from the onset on."""

    def jump(value: Any) -> Any:
        values = value.values.copy()
        values[0] += JUMP
        return dataclasses.replace(value, values=values)

    return _changed(messages, onset, POS, jump)


def scaled_imu(messages: list[Message], onset: int) -> list[Message]:
    """/cf1/imu's linear acceleration (all three axes) times ACCEL_SCALE from the onset on."""

    def scale(value: Any) -> Any:
        a = value.linear_acceleration
        scaled = dataclasses.replace(
            a, x=a.x * ACCEL_SCALE, y=a.y * ACCEL_SCALE, z=a.z * ACCEL_SCALE
        )
        return dataclasses.replace(value, linear_acceleration=scaled)

    return _changed(messages, onset, IMU, scale)


def second_publisher(messages: list[Message], onset: int) -> list[Message]:
    """From the onset on, a second connection on /cf1/log_pos under the callerid INTRUDER
    publishes a copy of each message 1 ms after it."""
    extra = [
        Message(dataclasses.replace(m.topic, callerid=INTRUDER), m.time + 1_000_000, m.raw)
        for m in messages
        if m.topic.topic == POS and m.time >= onset
    ]
    return sorted([*messages, *extra], key=lambda m: m.time)


FAULTS: dict[str, Inject] = {
    "slowed topic": slowed_topic,
    "dead topic": dead_topic,
    "frozen sensor": frozen_sensor,
    "position jump": position_jump,
    "scaled IMU": scaled_imu,
    "second publisher": second_publisher,
}
"""The faults injected into sine_2: each takes its messages and the onset (ns) and returns
the faulty messages."""


# --- scoring -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Outcome:
    """One replayed run: its group (fault class, or ``nominal``), onset and alarm times (s)."""

    name: str
    group: str
    onset: float | None
    alarms: tuple[float, ...]
    violations: int = 0
    error: str | None = None
    start: float = 0.0
    """The bag's start (s), for times printed from the start."""
    violated: float | None = None
    """The first violation at or after the onset (any violation of a nominal run): where
    the alarm rule starts from (:func:`print_sources`)."""
    cause: str | None = None
    """What raised the run's first alarm (its point, rule and invariant), if any."""

    @property
    def first(self) -> float | None:
        return min(self.alarms) if self.alarms else None

    @property
    def before(self) -> int:
        """Alarms before the onset (every alarm of a nominal run)."""
        if self.onset is None:
            return len(self.alarms)
        return sum(t < self.onset for t in self.alarms)

    @property
    def after(self) -> float | None:
        """The first alarm at or after the onset."""
        if self.onset is None:
            return None
        found = [t for t in self.alarms if t >= self.onset]
        return min(found) if found else None

    @property
    def delay(self) -> float | None:
        """First alarm at or after the onset minus the onset."""
        after = self.after
        return None if after is None or self.onset is None else after - self.onset

    @property
    def violation_delay(self) -> float | None:
        """First violation at or after the onset minus the onset."""
        if self.violated is None or self.onset is None:
            return None
        return self.violated - self.onset

    @property
    def detected(self) -> bool:
        """A fault run whose first alarm is at or after its onset."""
        first = self.first
        return self.onset is not None and first is not None and first >= self.onset

    @property
    def false_alarm(self) -> bool:
        return self.before > 0


def outcome(name: str, group: str, onset: float | None, result: RunResult) -> Outcome:
    """The outcome of one replay (alarm times in bag-clock seconds)."""
    after = [v.time for v in result.violations if onset is None or v.time >= onset]
    first = min(result.alarms, key=lambda a: a.time) if result.alarms else None
    return Outcome(
        name,
        group,
        onset,
        tuple(sorted(a.time for a in result.alarms)),
        len(result.violations),
        result.error,
        result.start,
        min(after) if after else None,
        None if first is None else alarm_cause(first),
    )


def alarm_cause(alarm: Alarm) -> str:
    """What raised ``alarm``: its point, the rule, the invariant and its text."""
    violation = alarm.violation
    return f"{alarm.point}, {alarm.rule}: {violation.invariant} {violation.text}"


@dataclass(frozen=True)
class Score:
    """Detection figures over a set of runs (see the module's docstring)."""

    runs: int
    faulty: int
    detected: int
    false_alarms: int
    alarmed: int
    delays: tuple[float, ...]

    @property
    def recall(self) -> float:
        return self.detected / self.faulty if self.faulty else math.nan

    @property
    def precision(self) -> float:
        return self.detected / self.alarmed if self.alarmed else math.nan

    @property
    def false_rate(self) -> float:
        return self.false_alarms / self.runs if self.runs else math.nan

    @property
    def mean_delay(self) -> float:
        return sum(self.delays) / len(self.delays) if self.delays else math.nan

    @property
    def max_delay(self) -> float:
        return max(self.delays) if self.delays else math.nan


def score(outcomes: Iterable[Outcome]) -> Score:
    """Recall, false alarms, precision and delays of a set of runs."""
    found = list(outcomes)
    detected = [o for o in found if o.detected]
    return Score(
        runs=len(found),
        faulty=sum(o.onset is not None for o in found),
        detected=len(detected),
        false_alarms=sum(o.false_alarm for o in found),
        alarmed=sum(bool(o.alarms) for o in found),
        delays=tuple(o.delay for o in detected if o.delay is not None),
    )


# --- ALFA folds ----------------------------------------------------------------------------

SESSION = re.compile(r"\d{4}-\d{2}-\d{2}-\d{2}-\d{2}-\d{2}")


def session_of(name: str) -> str:
    """The recording session of an ALFA flight: the date-time stamp in its file name."""
    found = SESSION.search(Path(name).name)
    return found.group(0) if found else Path(name).stem


SESSIONS = 0
"""``--folds session``: one fold per recording session (leave one session out)."""


def session_folds(names: Iterable[str], folds: int) -> list[list[str]]:
    """``folds`` folds of flights (fewer when there are fewer sessions; one per session with
    :data:`SESSIONS`), no session split: sessions, largest first (then by stamp), each go to
    the fold with the fewest flights."""
    sessions: dict[str, list[str]] = {}
    for name in sorted(names):
        sessions.setdefault(session_of(name), []).append(name)
    count = len(sessions) if folds == SESSIONS else min(folds, len(sessions))
    out: list[list[str]] = [[] for _ in range(max(1, count))]
    for _, flights in sorted(sessions.items(), key=lambda s: (-len(s[1]), s[0])):
        smallest = min(range(len(out)), key=lambda i: (len(out[i]), i))
        out[smallest].extend(flights)
    return [sorted(fold) for fold in out if fold]


# --- learning and replaying ----------------------------------------------------------------


def write_config(path: Path, project: str, scope: str, bags: Sequence[Path]) -> Path:
    """An imROS configuration: ``scope`` (XML text) and a <detect> of ``bags``."""
    listed = "\n".join(f"    <bag>{escape(str(bag.resolve()))}</bag>" for bag in bags)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        f'<imROS project="{project}">\n  {scope}\n  <detect inv="{project}.inv">\n'
        f"{listed}\n  </detect>\n</imROS>\n"
    )
    return path


@dataclass(frozen=True)
class Classification:
    """A classifying <check>: successful runs, failed runs, and how the failed runs' fault
    onset is found (a label topic or seconds after each bag's start; neither: unknown)."""

    success: Sequence[Path]
    fail: Sequence[Path]
    onset_topic: str | None = None
    onset: float | None = None


def set_check(config: Path, inv: str, classification: Classification) -> Path:
    """Rewrite ``config`` with a <check inv=``inv``> of ``classification`` in place of its
    own <check> (if any): one <success> per successful run, one <fail> per failed run."""
    tree = etree.parse(str(config))
    root = tree.getroot()
    check = etree.Element("check", inv=inv)
    if SELECT[0] is not None:
        check.set("select", SELECT[0])
    if DETECTOR[0] is not None:
        check.set("detector", DETECTOR[0])
    check.text = "\n    "
    entries: list[etree._Element] = []
    for bag in classification.success:
        entry = etree.SubElement(check, "success")
        entry.text = str(bag.resolve())
        entries.append(entry)
    for bag in classification.fail:
        entry = etree.SubElement(check, "fail")
        if classification.onset_topic is not None:
            entry.set("onset_topic", classification.onset_topic)
        if classification.onset is not None:
            entry.set("onset", repr(classification.onset))
        entry.text = str(bag.resolve())
        entries.append(entry)
    for entry in entries:
        entry.tail = "\n    "
    if entries:
        entries[-1].tail = "\n  "
    former, detect = root.find("check"), root.find("detect")
    if former is not None:
        check.tail = former.tail
        root.replace(former, check)
    elif detect is not None:
        check.tail = detect.tail
        detect.tail = "\n  "
        detect.addnext(check)
    else:
        root[-1].tail = "\n  "
        check.tail = "\n"
        root.append(check)
    config.write_bytes(etree.tostring(tree, encoding="utf-8") + b"\n")
    return config


BUDGET: list[float | None] = [None]
"""The false-alarm budget every part learns with (``--budget``; None: imrosc's default)."""
SELECT: list[str | None] = [None]
"""How classification chooses its invariants (``--select``; None: imrosc's default)."""
DETECTOR: list[str | None] = [None]
"""Whether classification learns fault detectors (``--detector``; None: imrosc's default)."""
STEP_TAIL: list[str | None] = [None]
"""How steps' margins model the units' largest steps (``--step-tail``, ``<detect
step_tail>``; None: imrosc's default)."""


def learn(config: Path, bags: Sequence[Path], workers: int | None) -> dict[str, Any]:
    """The invariants document ``run_detect`` gives (exits with its diagnostics if none);
    ``--step-tail`` is written into ``config``'s <detect> first."""
    if STEP_TAIL[0] is not None:
        tree = etree.parse(str(config))
        detect = tree.getroot().find("detect")
        assert detect is not None, config
        detect.set("step_tail", STEP_TAIL[0])
        tree.write(str(config))
    result = run_detect(config, bags=list(bags), workers=workers, budget=BUDGET[0])
    if result.document is None:
        sys.exit(f"inference failed for {config}:\n{render_text(result.diagnostics, 1)}")
    return result.document


EXPECTED = "success-in-detect"
"""The warning a classification here would give if a file kept no held-out replay of its
successful runs (they are the training runs)."""


def refine(
    config: Path, document: dict[str, Any], workers: int | None
) -> tuple[dict[str, Any], list[Diagnostic], dict[str, Any]]:
    """The refined document ``imrosc.classify.run_check`` gives for ``config``'s <check>
    with ``document`` as its invariants file (both written next to the configuration), its
    diagnostics and its report; exits with the diagnostics if it gives none."""
    inv = config.with_suffix(".inv")
    inv.write_text(dumps(document))
    out = inv.with_name(inv.stem + ".refined.inv")
    result = run_check(config, inv=inv, output=out, workers=workers)
    if result.refined is None or has_errors(result.diagnostics):
        sys.exit(f"classification failed for {config}:\n{render_text(result.diagnostics, 1)}")
    out.write_text(dumps(result.refined))
    return result.refined, result.diagnostics, result.report


def describe_detectors(report: Mapping[str, Any]) -> str:
    """The learnt detectors a classification's report lists: kept and refused (chance
    explains their held-out detections; docs/families/detector.md), with their points;
    and the monitor kept among the candidates, with each one's held-out worth."""
    kept = sorted(
        f"{d['point']}: {d['held_out_nominal']} held-out nominal runs"
        for d in report.get("detectors", ())
    )
    refused = sorted(d["point"] for d in report.get("detectors_refused", ()))
    found = (
        f"detectors {len(kept)} learnt ({', '.join(kept) or '-'}), "
        f"{len(refused)} refused ({', '.join(refused) or '-'})"
    )
    cover = report.get("cover") or {}
    if "monitor" in cover:
        worth = ", ".join(f"{w['monitor']} {fmt(w['value'])}" for w in cover.get("held_out", ()))
        found += f"; monitor kept: {cover['monitor']} (held-out worth: {worth})"
    return found


def describe_warnings(diagnostics: Sequence[Diagnostic]) -> str:
    """The diagnostics' codes with their counts; the expected one marked so."""
    counts: dict[str, int] = {}
    for d in diagnostics:
        counts[d.code] = counts.get(d.code, 0) + 1
    if not counts:
        return "none"
    return ", ".join(
        f"{code}" + (f" x{n}" if n > 1 else "") + (" (expected)" if code == EXPECTED else "")
        for code, n in sorted(counts.items())
    )


def describe_rule(document: dict[str, Any]) -> str:
    rule = document.get("alarms")
    return json.dumps(rule, sort_keys=True) if rule else "none (every violation alarms)"


def crazyflie_scope() -> str:
    """The <scope> of examples/crazyflie.xml, as XML text."""
    tree = etree.parse(str(ROOT / "examples" / "crazyflie.xml"))
    scope = tree.getroot().find("scope")
    assert scope is not None
    scope.tail = None
    return etree.tostring(scope, encoding="unicode")


def fmt(value: float | None, digits: int = 2) -> str:
    """A figure, or "-" when there is none (no minus sign on a rounded zero)."""
    if value is None or math.isnan(value):
        return "-"
    return f"{round(value, digits) + 0.0:.{digits}f}"


def print_outcomes(outcomes: Sequence[Outcome]) -> None:
    """One line per run: alarms, alarms before the onset, first alarm, delay."""
    width = max([len(o.name) for o in outcomes] + [3])
    group = max([len(o.group) for o in outcomes] + [5])
    print(
        f"  {'run':<{width}}  {'class':<{group}} {'onset s':>8} {'alarms':>6} {'before':>6} "
        f"{'first s':>8} {'delay s':>8}  detected"
    )
    for o in outcomes:
        onset = None if o.onset is None else o.onset - o.start
        first = None if o.first is None else o.first - o.start
        mark = "error: " + o.error if o.error else ("yes" if o.detected else "no")
        if o.onset is None:
            mark = o.error or "(nominal)"
        print(
            f"  {o.name:<{width}}  {o.group:<{group}} {fmt(onset):>8} {len(o.alarms):>6} "
            f"{o.before:>6} {fmt(first):>8} {fmt(o.delay):>8}  {mark}"
        )


def verdict(o: Outcome) -> str:
    """A run in a word: detected, missed, false alarm (before the onset, or on a nominal run),
    quiet (a nominal run without an alarm), or its error."""
    if o.error:
        return "error: " + o.error
    if o.false_alarm:
        return "false alarm"
    if o.onset is None:
        return "quiet"
    return "detected" if o.detected else "missed"


def groups_of(outcomes: Iterable[Outcome]) -> dict[str, list[Outcome]]:
    """The runs of each group (fault class, or nominal), groups sorted, then ``overall``."""
    found: dict[str, list[Outcome]] = {}
    everything = list(outcomes)
    for o in everything:
        found.setdefault(o.group, []).append(o)
    return {**dict(sorted(found.items())), "overall": everything}


def side_by_side(monitors: Mapping[str, Sequence[Outcome]]) -> dict[str, dict[str, Score]]:
    """Per group (each class, then ``overall``), per monitor, the score of its runs.

    ``monitors``: per monitor (one invariants document), the same runs replayed under it, in
    the same order (a ValueError otherwise)."""
    runs = [[(o.name, o.group, o.onset) for o in found] for found in monitors.values()]
    if any(r != runs[0] for r in runs[1:]):
        raise ValueError("the monitors were not scored on the same runs")
    table: dict[str, dict[str, Score]] = {}
    for monitor, found in monitors.items():
        for group, members in groups_of(found).items():
            table.setdefault(group, {})[monitor] = score(members)
    return table


def print_side_by_side(monitors: Mapping[str, Sequence[Outcome]]) -> None:
    """One line per run: its onset, then per monitor its alarms, first alarm, delay and
    verdict (times in s from the run's start)."""
    found = list(monitors.values())
    side_by_side(monitors)  # the same runs
    first = found[0]
    width = max([len(o.name) for o in first] + [3])
    group = max([len(o.group) for o in first] + [5])
    cell = 6 + 1 + 8 + 1 + 8 + 2 + 11
    lead = f"  {'':<{width}}  {'':<{group}} {'':>8}"
    print((lead + "".join(f" | {m:^{cell}}" for m in monitors)).rstrip())
    head = f"{'alarms':>6} {'first s':>8} {'delay s':>8}  {'verdict':<11}"
    line = f"  {'run':<{width}}  {'class':<{group}} {'onset s':>8}" + f" | {head}" * len(found)
    print(line.rstrip())
    for row in zip(*found, strict=True):
        o = row[0]
        onset = None if o.onset is None else o.onset - o.start
        line = f"  {o.name:<{width}}  {o.group:<{group}} {fmt(onset):>8}"
        for r in row:
            at = None if r.first is None else r.first - r.start
            line += f" | {len(r.alarms):>6} {fmt(at):>8} {fmt(r.delay):>8}  {verdict(r):<11}"
        print(line.rstrip())


def print_false_alarms(monitors: Mapping[str, Sequence[Outcome]]) -> None:
    """Per monitor, each run with an alarm before its onset (any alarm of a nominal run):
    when its first alarm was (s from the run's start) and what raised it."""
    print("false alarms (first alarm, s from the start, and what raised it):")
    found = False
    for monitor, runs in monitors.items():
        for o in runs:
            if o.false_alarm and o.first is not None:
                found = True
                print(f"  {monitor} {o.name}: {fmt(o.first - o.start)} s, {o.cause or '?'}")
    if not found:
        print("  none")


def print_scores(table: Mapping[str, Mapping[str, Score]]) -> None:
    """Per group and monitor: runs, detected, recall, false-alarm runs, precision, delays."""
    group = max([len(g) for g in table] + [5])
    monitor = max([len(m) for scores in table.values() for m in scores] + [7])
    print(
        f"  {'class':<{group}} {'monitor':<{monitor}} {'runs':>4} {'faulty':>6} "
        f"{'detected':>8} {'recall':>6} {'false-alarm runs':>17} {'precision':>9} "
        f"{'mean delay':>10} {'max delay':>9}"
    )
    for name, scores in table.items():
        for index, (label, s) in enumerate(scores.items()):
            shown = name if index == 0 else ""
            print(
                f"  {shown:<{group}} {label:<{monitor}} {s.runs:>4} {s.faulty:>6} "
                f"{s.detected:>8} {fmt(s.recall):>6} {s.false_alarms:>9} "
                f"({fmt(s.false_rate * 100, 0):>3} %) {fmt(s.precision):>9} "
                f"{fmt(s.mean_delay):>10} {fmt(s.max_delay):>9}"
            )


def print_sources(monitors: Mapping[str, Sequence[Outcome]]) -> None:
    """Where each detection's delay comes from, per fault run and monitor: the first
    violation at or after the onset (the signal), the first alarm at or after it, and what
    the alarm rule added between them; then, per monitor, their means over the runs it
    detected (an alarm may also come from an episode that began before the onset, so a
    run's figure can be negative)."""
    found = list(monitors.values())
    side_by_side(monitors)  # the same runs
    faulty = [k for k, o in enumerate(found[0]) if o.onset is not None]
    mean = "mean (detected)"
    width = max([len(found[0][k].name) for k in faulty] + [len(mean)])
    cell = f"{'violation':>9} {'alarm':>6} {'rule':>6}"
    print(("  " + " " * width + "".join(f" | {m:^{len(cell)}}" for m in monitors)).rstrip())
    print(f"  {'run':<{width}}" + f" | {cell}" * len(found))
    for k in faulty:
        line = f"  {found[0][k].name:<{width}}"
        for runs in found:
            o = runs[k]
            signal, alarm = o.violation_delay, o.delay
            added = None if alarm is None or signal is None else alarm - signal
            line += f" | {fmt(o.violation_delay):>9} {fmt(o.delay):>6} {fmt(added):>6}"
        print(line.rstrip())
    line = f"  {mean:<{width}}"
    for runs in found:
        caught = [runs[k] for k in faulty if runs[k].detected]
        signals = [o.violation_delay for o in caught if o.violation_delay is not None]
        alarms = [o.delay for o in caught if o.delay is not None]
        mean_signal = sum(signals) / len(signals) if signals else None
        mean_alarm = sum(alarms) / len(alarms) if alarms else None
        added = None if mean_signal is None or mean_alarm is None else mean_alarm - mean_signal
        line += f" | {fmt(mean_signal):>9} {fmt(mean_alarm):>6} {fmt(added):>6}"
    print(line.rstrip())


def target_figures(s: Score) -> str:
    """The figures the ALFA target rests on."""
    return (
        f"recall {fmt(s.recall)}, false alarms on {fmt(s.false_rate * 100, 0)} % of flights, "
        f"mean delay {fmt(s.mean_delay)} s"
    )


# --- the parts -----------------------------------------------------------------------------


@dataclass
class Verdicts:
    """Each target's verdict (None: its part did not run)."""

    found: dict[str, bool | None] = dataclasses.field(
        default_factory=lambda: dict.fromkeys(TARGETS)
    )
    figures: dict[str, str] = dataclasses.field(default_factory=dict)

    def set(self, index: int, ok: bool, figures: str) -> None:
        """Target ``index`` of TARGETS: its verdict and the figures it rests on."""
        self.found[TARGETS[index]] = ok
        self.figures[TARGETS[index]] = figures


MONITORS = ("inferred", "classified")
"""The two documents each part replays: inferred (A) and classified (B, A refined)."""


@dataclass(frozen=True)
class Flights:
    """Labelled ALFA flights: their folder and its ``onsets.json`` (per bag, relative to the
    folder: class, start, end and onset in ns, the onset null for a no-failure flight)."""

    root: Path
    onsets: dict[str, dict[str, Any]]


def read_flights(root: Path) -> Flights:
    """The flights of ``root`` as ``onsets.json`` lists them (exits naming the file and the
    problem if it is missing, not JSON, or names a bag that is not there)."""
    listing = root / "onsets.json"
    try:
        onsets = json.loads(listing.read_text())
    except (OSError, ValueError) as error:
        sys.exit(f"{listing}: cannot read the flights' onsets: {error}")
    if not isinstance(onsets, dict) or not all(
        isinstance(info, dict) and "onset_ns" in info and "class" in info
        for info in onsets.values()
    ):
        sys.exit(f"{listing}: not a mapping of bag to its class and onset_ns")
    missing = sorted(name for name in onsets if not (root / name).is_file())
    if missing:
        sys.exit(f"{listing}: {len(missing)} listed bags are missing, first {root / missing[0]}")
    return Flights(root, onsets)


def pre_onset_copies(work: Path, flights: Flights) -> dict[str, Path]:
    """Per flight, the bag a monitor learns from: a no-failure flight whole, a fault flight's
    copy up to its onset (written under ``work``)."""
    started = time.monotonic()
    training: dict[str, Path] = {}
    for name, info in sorted(flights.onsets.items()):
        if info["onset_ns"] is None:
            training[name] = flights.root / name
        else:
            training[name] = crop(flights.root / name, int(info["onset_ns"]), work / name)
    copies = sum(i["onset_ns"] is not None for i in flights.onsets.values())
    print(f"wrote {copies} pre-onset copies in {time.monotonic() - started:.1f} s")
    return training


def learn_alfa(
    work: Path,
    names: Sequence[str],
    flights: Flights,
    training: Mapping[str, Path],
    workers: int | None,
) -> dict[str, dict[str, Any]]:
    """Both monitors learnt from ``names``: inferred on their training bags, classified with
    those as <success> and the fault flights whole as <fail onset_topic> (printed)."""
    bags = [training[n] for n in names]
    faults = [flights.root / n for n in names if flights.onsets[n]["onset_ns"] is not None]
    config = write_config(work / "alfa.xml", "alfa", ALFA_SCOPE, bags)
    tick = time.monotonic()
    document = learn(config, bags, workers)
    learnt = time.monotonic() - tick
    set_check(config, "alfa.inv", Classification(bags, faults, onset_topic=ALFA_LABEL))
    tick = time.monotonic()
    refined, diagnostics, report = refine(config, document, workers)
    classified = time.monotonic() - tick
    print(
        f"  {len(bags)} training bags ({len(bags) - len(faults)} no-failure flights, "
        f"{len(faults)} pre-onset copies), {len(faults)} fault flights"
    )
    print(
        f"  inferred:   {len(document['invariants'])} invariants, alarm rule "
        f"{describe_rule(document)} ({learnt:.1f} s)"
    )
    print(
        f"  classified: {len(refined['invariants'])} kept, "
        f"{refined['classified']['dropped']} dropped, alarm rule {describe_rule(refined)} "
        f"({classified:.1f} s); warnings: {describe_warnings(diagnostics)}; "
        f"{describe_detectors(report)}"
    )
    return {"inferred": document, "classified": refined}


def replay_alfa(
    documents: Mapping[str, dict[str, Any]],
    flights: Flights,
    names: Sequence[str],
    outcomes: Mapping[str, list[Outcome]],
) -> None:
    """Replay ``names`` whole with each monitor, their outcomes added to ``outcomes``."""
    tick = time.monotonic()
    for monitor, used in documents.items():
        replayer = Replayer(used)
        for name in names:
            info = flights.onsets[name]
            onset = None if info["onset_ns"] is None else info["onset_ns"] / SECOND
            group = info["class"] if onset is not None else "no_failure"
            result = replayer.run(flights.root / name)
            outcomes[monitor].append(outcome(name, group, onset, result))
    print(f"  replayed {len(names)} flights with both in {time.monotonic() - tick:.1f} s")


def report_alfa(outcomes: Mapping[str, list[Outcome]]) -> dict[str, dict[str, Score]]:
    """Print every flight under both monitors, the scores per class and where the delays
    come from; the scores."""
    for found in outcomes.values():
        found.sort(key=lambda o: o.name)
    named = {
        monitor: [
            dataclasses.replace(o, name=Path(o.name).stem.removeprefix("carbonZ_")) for o in found
        ]
        for monitor, found in outcomes.items()
    }
    print("\nflights (times in s from the bag's start):")
    print_side_by_side(named)
    print_false_alarms(named)
    print("\nper class (precision: detected / flights with any alarm):")
    table = side_by_side(outcomes)
    print_scores(table)
    print(
        "\nwhere the delays come from (s after the onset: first violation, first alarm, "
        "and what the alarm rule added between them):"
    )
    print_sources(named)
    return table


def alfa_verdict(verdicts: Verdicts, index: int, table: Mapping[str, Mapping[str, Score]]) -> None:
    s, inferred = table["overall"]["classified"], table["overall"]["inferred"]
    verdicts.set(
        index,
        s.recall >= ALFA_RECALL and s.false_rate <= ALFA_FALSE and s.mean_delay <= ALFA_DELAY,
        f"classified: {target_figures(s)}; inferred: {target_figures(inferred)}",
    )


def alfa_part(work: Path, folds: int, workers: int | None, verdicts: Verdicts) -> None:
    flights = read_flights(ALFA)
    split = session_folds(flights.onsets, folds)
    scheme = "leave one session out" if folds == SESSIONS else "by recording session"
    print(f"\n== ALFA: {len(flights.onsets)} flights, {len(split)}-fold {scheme} ==")
    print(f"reference to beat: {REFERENCE}")
    training = pre_onset_copies(work / "pre_onset", flights)
    print(
        "per fold: infer on the other folds' pre-onset copies and no-failure flights "
        "(inferred); classify with those as <success> and the other folds' fault flights whole "
        f'as <fail onset_topic="{ALFA_LABEL}"> (classified); replay the fold\'s flights whole '
        "with both"
    )
    outcomes: dict[str, list[Outcome]] = {m: [] for m in MONITORS}
    for index, held in enumerate(split):
        sessions = sorted({session_of(n) for n in held})
        print(f"fold {index}: {len(held)} flights of {len(sessions)} sessions held out")
        names = [n for n in sorted(flights.onsets) if n not in held]
        documents = learn_alfa(work / f"fold_{index}", names, flights, training, workers)
        replay_alfa(documents, flights, held, outcomes)
    alfa_verdict(verdicts, 0, report_alfa(outcomes))


def held_out_part(work: Path, test: Flights, workers: int | None, verdicts: Verdicts) -> None:
    """Learn both monitors once from every development flight, replay ``test``'s flights."""
    development = read_flights(ALFA)
    print(
        f"\n== ALFA held out: learn on the {len(development.onsets)} development flights, "
        f"replay the {len(test.onsets)} flights of {test.root} =="
    )
    print(f"reference to beat: {REFERENCE}")
    seen = sorted({Path(n).name for n in development.onsets} & {Path(n).name for n in test.onsets})
    if seen:
        print(f"warning: {len(seen)} test flights are development flights too, first {seen[0]}")
    training = pre_onset_copies(work / "pre_onset", development)
    documents = learn_alfa(work / "all", sorted(development.onsets), development, training, workers)
    outcomes: dict[str, list[Outcome]] = {m: [] for m in MONITORS}
    replay_alfa(documents, test, sorted(test.onsets), outcomes)
    alfa_verdict(verdicts, len(TARGETS) - 1, report_alfa(outcomes))


def _replay_line(label: str, result: RunResult) -> str:
    first = min(result.alarms, key=lambda a: a.time) if result.alarms else None
    text = f"  {label}: {len(result.alarms)} alarms, {len(result.violations)} violations"
    if result.error:
        text += f", error: {result.error}"
    if first is not None:
        text += f"; first {first.describe()} ({first.time - result.start:.2f} s from the start)"
    return text


def crazyflie_part(work: Path, workers: int | None, verdicts: Verdicts) -> None:
    print("\n== Crazyflie: examples/crazyflie.xml's scope ==")
    scope = crazyflie_scope()
    sine_1, sine_2 = CRAZYFLIE / "sine_1.bag", CRAZYFLIE / "sine_2.bag"
    config = write_config(work / "sine_1" / "crazyflie.xml", "crazyflie", scope, [sine_1])
    document = learn(config, [sine_1], workers)
    print(
        f"learnt on sine_1: {len(document['invariants'])} invariants, "
        f"alarm rule {describe_rule(document)}"
    )
    replayer = Replayer(document)
    held_out = replayer.run(sine_2)
    own = replayer.run(sine_1)
    print(_replay_line("sine_2 (held out)", held_out))
    print(_replay_line("sine_1 (training)", own))
    verdicts.set(
        1,
        not held_out.alarms and held_out.error is None,
        f"{len(held_out.alarms)} alarms, {len(held_out.violations)} violations",
    )

    both = [sine_1, sine_2]
    config = write_config(work / "sine_1_2" / "crazyflie.xml", "crazyflie", scope, both)
    document = learn(config, both, workers)
    print(
        f"learnt on sine_1 and sine_2: {len(document['invariants'])} invariants, "
        f"alarm rule {describe_rule(document)}"
    )
    replayer = Replayer(document)
    trained = [replayer.run(bag) for bag in both]
    for path, result in zip(both, trained, strict=True):
        print(_replay_line(f"{path.name} (training)", result))
    own_alarms = len(own.alarms) + sum(len(r.alarms) for r in trained)
    verdicts.set(3, own_alarms == 0, f"{own_alarms} alarms over the 3 training replays")

    bag = read_bag(sine_2)
    onset = bag.start + round(FAULT_AT * (bag.end - bag.start))
    print(
        f"faults injected into sine_2 from {(onset - bag.start) / SECOND:.2f} s "
        f"({FAULT_AT:.0%} of {(bag.end - bag.start) / SECOND:.2f} s):"
    )
    outcomes = []
    for name, inject in FAULTS.items():
        path = write_bag(
            work / "faults" / f"{name.replace(' ', '_')}.bag",
            inject(bag.messages, onset),
            bag.topics,
        )
        result = replayer.run(path)
        outcomes.append(outcome(name, "injected", onset / SECOND, result))
    print_outcomes(outcomes)
    print("  where the delays come from (s after the onset):")
    print_sources({"learnt on both": outcomes})
    ok = all(
        o.detected and o.delay is not None and o.delay <= FAULT_DELAY and o.before == 0
        for o in outcomes
    )
    caught = sum(o.detected and o.delay is not None and o.delay <= FAULT_DELAY for o in outcomes)
    verdicts.set(
        2,
        ok,
        f"{caught} of {len(outcomes)} detected within {FAULT_DELAY} s, "
        f"{sum(o.before for o in outcomes)} alarms before the onsets",
    )


def sim_part(work: Path, workers: int | None, verdicts: Verdicts) -> None:
    from imrosc.demo import CONFIG, example_configs
    from imrosc.sim import SCENARIO_KINDS, Scenario, write_run, write_runs
    from imrosc.sim.recording import START_NS

    print(f"\n== Simulated landing system ({CONFIG}): learn on {SIM_NOMINAL} nominal runs ==")
    source = next(p for p in example_configs() if p.name == CONFIG)
    config = work / CONFIG
    shutil.copyfile(source, config)
    shutil.copyfile(source.with_name("landing_sim.graph.yaml"), work / "landing_sim.graph.yaml")
    tick = time.monotonic()
    nominal = write_runs(work / "bags" / "nominal", runs=SIM_NOMINAL, seed=0, fmt="ros1")
    held = write_runs(work / "bags" / "held_out", runs=SIM_HELD_OUT, seed=100, fmt="ros1")

    def scenarios(folder: str, seed: int) -> list[Path]:
        return [
            write_run(
                work / "bags" / folder / f"{kind}.bag",
                seed=seed + index,
                fmt="ros1",
                scenario=Scenario(kind, start=SIM_START),
            )
            for index, kind in enumerate(SCENARIO_KINDS)
        ]

    faulty = scenarios("fail", 200)
    trained = scenarios("train_fail", 300)
    print(
        f"simulated {len(nominal) + len(held) + len(faulty) + len(trained)} runs in "
        f"{time.monotonic() - tick:.1f} s"
    )
    tick = time.monotonic()
    document = learn(config, nominal, workers)
    print(
        f"inferred:   {len(document['invariants'])} invariants, alarm rule "
        f"{describe_rule(document)} ({time.monotonic() - tick:.1f} s)"
    )
    inv = Path(CONFIG).with_suffix(".inv").name
    set_check(config, inv, Classification(nominal, trained, onset=SIM_START))
    tick = time.monotonic()
    refined, diagnostics, report = refine(config, document, workers)
    print(
        f"classified on the {len(nominal)} nominal runs as <success> and one run of each "
        f'scenario (seeds 300-{299 + len(trained)}) as <fail onset="{SIM_START:g}">: '
        f"{len(refined['invariants'])} kept, {refined['classified']['dropped']} dropped, "
        f"alarm rule {describe_rule(refined)} ({time.monotonic() - tick:.1f} s); "
        f"warnings: {describe_warnings(diagnostics)}; {describe_detectors(report)}"
    )
    start = START_NS / SECOND
    outcomes: dict[str, list[Outcome]] = {}
    for monitor, used in (("inferred", document), ("classified", refined)):
        replayer = Replayer(used)
        outcomes[monitor] = [
            outcome(f"nominal, seed {100 + i}", "nominal", None, replayer.run(b))
            for i, b in enumerate(held)
        ]
        outcomes[monitor] += [
            outcome(kind, kind, start + SIM_START, replayer.run(bag))
            for kind, bag in zip(SCENARIO_KINDS, faulty, strict=True)
        ]
    print(
        f"replayed (seeds 100-101 nominal, 200-{199 + len(faulty)} faulty; fault from "
        f"{SIM_START:.0f} s; times in s from the run's start):"
    )
    print_side_by_side(outcomes)
    table = side_by_side(outcomes)
    print_scores({"overall": table["overall"]})
    print("where the delays come from (s after the onset):")
    print_sources(outcomes)
    found = {m: [o for o in runs if o.onset is not None] for m, runs in outcomes.items()}
    caught = {m: sum(o.detected for o in runs) for m, runs in found.items()}
    verdicts.set(
        4,
        caught["classified"] == len(found["classified"]),
        f"classified: {caught['classified']} of {len(found['classified'])} scenarios detected; "
        f"inferred: {caught['inferred']} of {len(found['inferred'])}",
    )


def folds_of(text: str) -> int:
    """``--folds``: a number of folds, at least 2, or ``session`` (:data:`SESSIONS`)."""
    if text == "session":
        return SESSIONS
    try:
        folds = int(text)
    except ValueError:
        folds = 0
    if folds < 2:
        raise argparse.ArgumentTypeError(f'{text!r}: at least 2, or "session"')
    return folds


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default=",".join(PARTS), help="comma list of " + ", ".join(PARTS))
    parser.add_argument(
        "--folds",
        type=folds_of,
        default=5,
        help='ALFA folds, at least 2 (default 5), or "session": one per recording session',
    )
    parser.add_argument("-j", "--workers", type=int, default=None, help="inference workers")
    parser.add_argument("--keep", type=Path, default=None, help="keep the written bags here")
    parser.add_argument(
        "--budget", type=float, default=None, help="false-alarm budget (default: imrosc's)"
    )
    parser.add_argument(
        "--select",
        choices=("cover", "fscore"),
        default=None,
        help="how classify chooses the kept invariants (default: imrosc's, cover)",
    )
    parser.add_argument(
        "--detector",
        choices=("none", "logistic"),
        default=None,
        help="<check detector> of the classified monitors (default: imrosc's, logistic, "
        'docs/families/detector.md; "none": invariants only)',
    )
    parser.add_argument(
        "--step-tail",
        choices=("larger", "select"),
        default=None,
        help="<detect step_tail>: how steps' margins model the units' largest steps (default: "
        "imrosc's, select; docs/calibration.md section 4)",
    )
    parser.add_argument(
        "--alfa-test",
        type=Path,
        default=None,
        metavar="DIR",
        help="learn from every development ALFA flight and replay DIR's flights (bags and an "
        "onsets.json like shared/data/real/alfa's); only this part runs",
    )
    args = parser.parse_args(argv)
    BUDGET[0] = args.budget
    SELECT[0] = args.select
    DETECTOR[0] = args.detector
    STEP_TAIL[0] = args.step_tail
    parts = [p.strip() for p in args.only.split(",") if p.strip()]
    unknown = sorted(set(parts) - set(PARTS))
    if unknown:
        parser.error(f"unknown part {unknown}")
    if args.keep is not None and args.keep.exists() and any(args.keep.iterdir()):
        parser.error(f"--keep {args.keep}: not empty")
    test = read_flights(args.alfa_test) if args.alfa_test is not None else None
    print("Targets (issue 17):")
    for target in TARGETS:
        print(f"  - {target}")
    verdicts = Verdicts()
    scratch = tempfile.TemporaryDirectory(prefix="imrosc-efficacy-")
    work = args.keep if args.keep is not None else Path(scratch.name)
    started = time.monotonic()
    with scratch:
        if test is not None:
            held_out_part(work / "held_out", test, args.workers, verdicts)
        elif "alfa" in parts:
            if (ALFA / "onsets.json").is_file():
                alfa_part(work / "alfa", args.folds, args.workers, verdicts)
            else:
                print(f"\nALFA: {ALFA} missing, skipped")
        if "crazyflie" in parts and test is None:
            if (CRAZYFLIE / "sine_2.bag").is_file():
                crazyflie_part(work / "crazyflie", args.workers, verdicts)
            else:
                print(f"\nCrazyflie: {CRAZYFLIE} missing, skipped")
        if "sim" in parts and test is None:
            (work / "sim").mkdir(parents=True, exist_ok=True)
            sim_part(work / "sim", args.workers, verdicts)
    print(f"\nVerdicts ({time.monotonic() - started:.0f} s):")
    for target, ok in verdicts.found.items():
        word = "not run" if ok is None else ("MET" if ok else "NOT MET")
        figures = verdicts.figures.get(target, "")
        print(f"  {word:<8} {target}" + (f"  [{figures}]" if figures else ""))
    if args.keep is not None:
        print(f"bags and configurations kept in {args.keep}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
