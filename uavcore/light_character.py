"""Navigation-light characters as charts abbreviate them (IALA, IHO INT 1, S-57 LIGHTS), and reading one from frames.

`parse("Fl(2) G 6s")` gives a `LightCharacter`, whose `phases()` are its light and dark over one period;
`read_sequence` turns a camera's on/off frames into an `ObservedLight`, and `matches` says how that differs
from the chart. Pure computation.

IALA defines each class by its rhythm, not by durations, and a chart gives only the period, so the durations
inside a period are typical lantern values (phase 0 is the start of a group's first flash, or eclipse for Oc):
- Q 60 flashes a minute (0.3 s light in each 1 s), VQ 120 (0.2 s in 0.5 s), UQ 240 (0.1 s in 0.25 s): inside
  IALA's 50-79, 80-159 and >= 160 a minute, each flash shorter than the dark after it. The rate is the class,
  so these never shrink: a group that leaves no long dark in its period is refused.
- IQ, IVQ, IUQ: as many quick flashes as fit in the first three quarters of the period, then dark.
- Q(n)+LFl: n quick flashes, a quick flash's dark, a 2 s long flash, then dark (the south cardinal's light).
- LFl: a 2 s flash (IALA's shortest long flash), 2 s dark between the flashes of a group; never shrunk.
- Fl: 0.5 s flashes, 1 s dark between a group's flashes, 2 s between the parts of a composite group (2+1).
- Oc: 1 s eclipses, 1 s light between a group's eclipses, 2 s between composite parts.
- Mo: 0.5 s dot, 1.5 s dash, 0.5 s between a letter's signs, 1.5 s between letters (Morse's 1:3).
- Iso: half the period light, half dark.
- Fl, Oc and Mo groups take at most 45 % of the period (shrunk in proportion where a short period needs it):
  the closing dark (light, for Oc) then outlasts the group, and is what marks where the group repeats.
- Al: the period holds the whole colour sequence; the rhythm repeats once per colour, each time in the next one.
"""

from __future__ import annotations

import bisect
import math
import re
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from itertools import accumulate

import numpy as np

COLOURS = ("W", "R", "G", "Y", "Bu")  # white, red, green, yellow, blue (the emergency wreck marking's Al.BuY)
CLASSES = ("F", "Fl", "LFl", "Q", "VQ", "UQ", "IQ", "IVQ", "IUQ", "Iso", "Oc", "Mo")
KINDS = (*CLASSES, "Q+LFl", "VQ+LFl", "UQ+LFl")
LONG_FLASH_S = 2.0
MAX_GROUP_SHARE = 0.45
INTERRUPTED_SHARE = 0.75
FIXED_CYCLE_S = 1.0  # a fixed light has no rhythm: its one phase spans this unless a period is charted
# International Morse code of the letters, as Mo(A) etc. flash them
_MORSE = dict(zip("ABCDEFGHIJKLMNOPQRSTUVWXYZ", [
    ".-", "-...", "-.-.", "-..", ".", "..-.", "--.", "....", "..", ".---", "-.-", ".-..", "--",
    "-.", "---", ".--.", "--.-", ".-.", "...", "-", "..-", "...-", ".--", "-..-", "-.--", "--..",
], strict=True))  # fmt: skip


@dataclass(frozen=True)
class _Timing:
    mark_s: float  # a flash (an eclipse for Oc; a dot for Mo)
    gap_s: float  # the opposite phase between the marks of a group
    part_gap_s: float  # between the parts of a composite group, or the letters of a Morse group
    shrinks: bool  # scaled down to fit a short period, or fixed by the class's definition


_TIMING = {
    "Fl": _Timing(0.5, 1.0, 2.0, True),
    "LFl": _Timing(LONG_FLASH_S, 2.0, 4.0, False),
    "Oc": _Timing(1.0, 1.0, 2.0, True),
    "Mo": _Timing(0.5, 0.5, 1.5, True),
    "Q": _Timing(0.3, 0.7, 1.7, False),
    "VQ": _Timing(0.2, 0.3, 0.8, False),
    "UQ": _Timing(0.1, 0.15, 0.4, False),
}
_INTERRUPTED = {"IQ": "Q", "IVQ": "VQ", "IUQ": "UQ"}
_GROUPED = {"Fl", "LFl", "Oc", "Q", "VQ", "UQ"}  # the classes a chart may give a group count, e.g. Fl(2), Q(3)

Phase = tuple[bool, float]  # (lit, duration s)
Run = tuple[bool, float, float]  # (lit, start s, duration s)


class LightCharacterError(ValueError):
    """A light character that cannot be read, or that cannot be (a group too long for its period)."""


@dataclass(frozen=True)
class LightCharacter:
    """A light's character: class, group, colours and period, as a chart abbreviates it."""

    kind: str  # one of KINDS; "Q+LFl" is S-57's quick-flash plus long-flash (LITCHR 25)
    groups: tuple[int, ...] = ()  # flashes (eclipses for Oc) per part: (2,) Fl(2), (2, 1) Fl(2+1), (6,) Q(6)+LFl
    colours: tuple[str, ...] = ("W",)  # several and not alternating: a sector light, one colour per sector
    period_s: float | None = None
    alternating: bool = False  # Al.: the colours take turns
    morse: str = ""  # Mo's letters

    def __post_init__(self) -> None:
        name = self.abbreviation()
        if self.kind not in KINDS:
            raise LightCharacterError(f"{name}: unknown class {self.kind!r}")
        if not self.colours or any(c not in COLOURS for c in self.colours):
            raise LightCharacterError(f"{name}: colours must be among {' '.join(COLOURS)}")
        if self.groups and (self.kind.split("+")[0] not in _GROUPED or min(self.groups) < 1):
            raise LightCharacterError(f"{name}: {self.kind} takes no group {self.groups}")
        if self.kind.endswith("+LFl") and len(self.groups) != 1:
            raise LightCharacterError(f"{name}: +LFl follows a group of quick flashes, e.g. Q(6)+LFl")
        if (self.kind == "Mo") != bool(self.morse) or any(c not in _MORSE for c in self.morse):
            raise LightCharacterError(f"{name}: Mo needs its Morse letters, e.g. Mo(A), and only Mo has them")
        if self.alternating and len(self.colours) < 2:
            raise LightCharacterError(f"{name}: an alternating light needs two colours or more")
        if self.period_s is not None and not self.period_s > 0:
            raise LightCharacterError(f"{name}: the period must be positive")
        if self.cycle_s is not None:
            self.phases()  # builds them now, so that a group too long for its period fails here

    @property
    def cycle_s(self) -> float | None:
        """The period of the rhythm: the charted one, else the one the class implies (F, groupless Q/VQ/UQ)."""
        if self.period_s is not None or self.alternating:
            return self.period_s
        if self.kind == "F":
            return FIXED_CYCLE_S
        if self.kind in _TIMING and self.kind.endswith("Q") and not self.groups:
            return _TIMING[self.kind].mark_s + _TIMING[self.kind].gap_s
        return None

    @cached_property
    def _timeline(self) -> tuple[tuple[Phase, ...], list[float], float]:
        """The phases over one period, the time each ends, and the period."""
        period = self.cycle_s
        if period is None:
            raise LightCharacterError(f"{self.abbreviation()}: no period charted, and {self.kind} implies none")
        turns = len(self.colours) if self.alternating else 1
        phases = _rhythm(self, period / turns) * turns
        # the last phase takes what the others leave, so that the phases sum to the period exactly
        phases[-1] = (phases[-1][0], period - math.fsum(d for _, d in phases[:-1]))
        return tuple(phases), list(accumulate(d for _, d in phases)), period

    def phases(self) -> list[Phase]:
        """The (lit, duration s) sequence over one period, by the module's timing conventions."""
        return list(self._timeline[0])

    def is_on(self, t_s: float) -> bool:
        """Whether the light shows at simulated time t_s (0 = the start of a period)."""
        phases, ends, period = self._timeline
        return phases[min(bisect.bisect_right(ends, t_s % period), len(phases) - 1)][0]

    def colour_at(self, t_s: float) -> str | None:
        """The colour showing at t_s (None while dark); a sector light's first colour."""
        if not self.is_on(t_s):
            return None
        if not self.alternating:
            return self.colours[0]
        period = self._timeline[2]
        return self.colours[min(int(t_s % period / period * len(self.colours)), len(self.colours) - 1)]

    def abbreviation(self) -> str:
        """The chart's text, e.g. "Fl(2) G 6s", "Q(6)+LFl W 15s", "Al.WR", "Al.Fl WR 4s"."""
        rhythm, plus, suffix = self.kind.partition("+")
        counts = self.morse or "+".join(str(n) for n in self.groups)
        head = f"{rhythm}({counts}){plus}{suffix}" if counts else self.kind
        text = ("Al." if self.alternating else "") + ("" if self.alternating and head == "F" else f"{head} ")
        text += "".join(self.colours)
        return text if self.period_s is None else f"{text} {_number(self.period_s)}s"


def _number(value: float) -> str:
    return repr(value).removesuffix(".0")


def _rhythm(c: LightCharacter, period: float) -> list[Phase]:
    """One turn of the rhythm (the whole period unless the light alternates), by the conventions above."""
    if c.kind == "F":
        return [(True, period)]
    if c.kind == "Iso":
        return [(True, period / 2), (False, period / 2)]
    base = _INTERRUPTED.get(c.kind, c.kind.split("+")[0])
    t = _TIMING[base]
    if c.kind == "Mo":
        parts = [[t.mark_s * (3 if sign == "-" else 1) for sign in _MORSE[letter]] for letter in c.morse]
    elif c.kind in _INTERRUPTED:
        parts = [[t.mark_s] * max(1, int(INTERRUPTED_SHARE * period / (t.mark_s + t.gap_s)))]
    else:
        parts = [[t.mark_s] * n for n in c.groups or (1,)]
    if c.kind.endswith("+LFl"):
        parts[-1].append(LONG_FLASH_S)
    mark = base != "Oc"  # a flash marks the rhythm, except an occulting light's eclipse
    phases: list[Phase] = []
    for i, part in enumerate(parts):
        for j, duration in enumerate(part):
            if i or j:
                phases.append((not mark, t.gap_s if j else t.part_gap_s))
            phases.append((mark, duration))
    span = math.fsum(d for _, d in phases)
    scale = min(1.0, MAX_GROUP_SHARE * period / span) if t.shrinks else 1.0
    closing = period - span * scale
    # a group's closing dark must stand out from the darks inside it, or the group could not be told apart
    if closing < t.gap_s * scale * (2 if len(phases) > 1 else 1) - 1e-9:
        raise LightCharacterError(f"{c.abbreviation()}: its group lasts {span:g} s, too long for a {period:g} s period")
    return [(on, d * scale) for on, d in phases] + [(not mark, closing)]


_SEPARATORS = " \t.,"
_AL_RE = re.compile(r"al(?=[\s.])", re.I)
_CLASS_RE = re.compile("|".join(sorted(CLASSES, key=len, reverse=True)), re.I)
_GROUP_RE = re.compile(r"\(([^)]*)\)")
_COUNTS_RE = re.compile(r"\d+(\s*\+\s*\d+)*")
_PLUS_LFL_RE = re.compile(r"\+\s*LFl", re.I)
_COLOUR_RE = re.compile("|".join(sorted(COLOURS, key=len, reverse=True)), re.I)
_PERIOD_RE = re.compile(r"(\d+(?:\.\d+)?)\s*s(?:ec)?\b", re.I)


class _Cursor:
    """Reads a chart text token by token, skipping the spaces and dots charts put between them."""

    def __init__(self, text: str) -> None:
        self.text, self.pos = text, 0

    def take(self, pattern: re.Pattern[str]) -> re.Match[str] | None:
        while self.pos < len(self.text) and self.text[self.pos] in _SEPARATORS:
            self.pos += 1
        found = pattern.match(self.text, self.pos)
        if found:
            self.pos = found.end()
        return found

    def rest(self) -> str:
        """What is left unread, without the separators."""
        return self.text[self.pos :].strip(_SEPARATORS)


def parse(text: str) -> LightCharacter:
    """The character of a chart's light text, e.g. "Fl(2) G 6s", "Q(6)+LFl W 15s", "Al.WR", "Fl(2)G.6s".

    Case and spacing are free; colours left out mean white, as on charts. Raises LightCharacterError naming the
    part that could not be read.
    """
    cursor = _Cursor(text.strip())
    if not cursor.text:
        raise LightCharacterError("empty light character")
    alternating = cursor.take(_AL_RE) is not None
    found = cursor.take(_CLASS_RE)
    if found is None and not alternating:
        raise LightCharacterError(
            f"no light class at {cursor.rest()!r} in {text!r}: expected one of {' '.join(CLASSES)}"
        )
    kind = next(k for k in CLASSES if k.lower() == found.group().lower()) if found else "F"
    groups: tuple[int, ...] = ()
    morse = ""
    if group := cursor.take(_GROUP_RE):
        inside = group.group(1).strip()
        if kind == "Mo" and inside.isalpha():
            morse = inside.upper()
        elif _COUNTS_RE.fullmatch(inside):
            groups = tuple(int(n) for n in inside.split("+"))
        else:
            raise LightCharacterError(f"cannot read the group {inside!r} in {text!r}: expected (2), (2+1) or Mo(A)")
    if cursor.take(_PLUS_LFL_RE):
        if kind not in ("Q", "VQ", "UQ"):
            raise LightCharacterError(f"+LFl follows only Q, VQ or UQ, not {kind}, in {text!r}")
        kind += "+LFl"
    colours: list[str] = []
    while colour := cursor.take(_COLOUR_RE):
        colours.append(next(c for c in COLOURS if c.lower() == colour.group().lower()))
    period = cursor.take(_PERIOD_RE)
    if rest := cursor.rest():
        raise LightCharacterError(
            f"cannot read {rest!r} in {text!r}: expected colours ({' '.join(COLOURS)}) then a period like 6s"
        )
    period_s = float(period.group(1)) if period else None
    return LightCharacter(kind, groups, tuple(colours) or ("W",), period_s, alternating, morse)


_S57_LITCHR = {
    1: "F", 2: "Fl", 3: "LFl", 4: "Q", 5: "VQ", 6: "UQ", 7: "Iso", 8: "Oc", 9: "IQ", 10: "IVQ", 11: "IUQ", 12: "Mo",
    17: "Al.Oc", 18: "Al.LFl", 19: "Al.Fl", 25: "Q+LFl", 26: "VQ+LFl", 27: "UQ+LFl", 28: "Al.",
}  # fmt: skip
_S57_COLOUR = {1: "W", 3: "R", 4: "G", 5: "Bu", 6: "Y"}


def from_s57(litchr: int, siggrp: str = "", sigper: float | None = None, colour: str = "1") -> LightCharacter:
    """The character of an S-57 LIGHTS object: LITCHR code, SIGGRP ("(2)", "(2+1)", "(A)"), SIGPER (s) and COLOUR
    codes ("1" or "1,3"). LITCHR codes outside the classes above (13-16 fixed-and-flashing etc.) are refused.
    A group of one is no group: S-57 writes SIGGRP "(1)" for a single flash where charts print "Fl R 4s"."""
    codes = [int(code) for code in colour.split(",") if code.strip()]
    if litchr not in _S57_LITCHR or any(code not in _S57_COLOUR for code in codes):
        raise LightCharacterError(f"S-57 LITCHR {litchr} COLOUR {colour!r}: not a character this module reads")
    rhythm, plus, suffix = _S57_LITCHR[litchr].partition("+")
    group = "" if siggrp.strip() in ("", "()", "(1)") else siggrp.strip()
    period = "" if sigper is None else f" {_number(sigper)}s"
    return parse(f"{rhythm}{group}{plus}{suffix} {''.join(_S57_COLOUR[code] for code in codes)}{period}")


@dataclass(frozen=True)
class ObservedLight:
    """What frames of a light show: its rhythm, one group's pattern, the period it repeats in, and its colours."""

    rhythm: str  # "dark", "fixed", "flashing", "occulting", "isophase", or "unreadable": no whole group, or no repeat
    pattern: str = ""  # a group's flashes (eclipses if occulting): "." short, "-" long, "+" between composite parts
    period_s: float | None = None  # one colour's turn for an alternating light
    colour: str | None = None  # the most frequent colour of the lit frames
    colours: tuple[str, ...] = ()  # every colour of at least COLOUR_SHARE of the lit frames, most frequent first
    # the longest the light was seen dark and lit at a stretch (a run at the burst's edge counts as far as it was
    # seen), and the frame interval: even a burst too short for the light's rhythm can show it is not the chart's
    longest_dark_s: float | None = None
    longest_lit_s: float | None = None
    frame_interval_s: float | None = None

    @property
    def groups(self) -> tuple[int, ...]:
        """Flashes per part of a group: (2,) for "..", (2, 1) for "..+.", (7,) for Q(6)+LFl's "......-"."""
        return tuple(len(part) for part in self.pattern.split("+")) if self.pattern else ()


COLOUR_SHARE = 0.2
ISO_DUTY_SPREAD = 0.05  # isophase: lit 45-55 % of the time
QUICK_CYCLE_S = 60 / 50  # IALA's slowest quick light, 50 flashes a minute
SPREAD = 0.15  # durations of one class differ by up to this fraction, beyond what the frame interval explains
FRAME_SLACK = 3  # ... and this many frame intervals (each end of a run is placed within half an interval)
LONG_MARK_S = 0.8 * LONG_FLASH_S  # a lone flash this long reads as a long flash, whatever the sampling took off


def _floors(values: Sequence[float], dt: float) -> list[float]:
    """The shortest of each class of similar durations, ascending."""
    floors: list[float] = []
    for previous, value in zip([-math.inf, *sorted(values)], sorted(values), strict=False):
        if value - previous > SPREAD * previous + FRAME_SLACK * dt:
            floors.append(value)
    return floors


def _level(value: float, floors: list[float]) -> int:
    return bisect.bisect_right(floors, value) - 1  # -1: shorter than every class (a run the window cut)


def _structure(runs: list[Run], dt: float) -> tuple[str, str, float | None]:
    """(rhythm, pattern, period) of alternating lit and dark runs, the first and the last cut by the window."""
    lit = [d for on, _, d in runs[1:-1] if on]
    dark = [d for on, _, d in runs[1:-1] if not on]
    if not lit or not dark:
        return "unreadable", "", None
    # the share of the time lit over whole cycles (from a lit run, as many dark runs as lit): a frame flipped or
    # missing at a run's end moves it by a frame, a small part of the sum
    paired = runs[1:-1][0 if runs[1][0] else 1 :]
    paired = paired[: len(paired) // 2 * 2]
    if not paired:
        return "unreadable", "", None
    total = math.fsum(d for _, _, d in paired)
    duty = math.fsum(d for on, _, d in paired if on) / total
    # isophase: light and dark equal (but for two frames' worth), each of one length, and slower than the quick
    # classes (a rhythm of 50 or more a minute is quick, and a camera frame is then a fair part of a phase)
    if (
        abs(duty - 0.5) <= ISO_DUTY_SPREAD + 2 * dt / total
        and 2 * total / len(paired) > QUICK_CYCLE_S
        and len(_floors(lit, dt)) == len(_floors(dark, dt)) == 1
    ):
        rhythm, mark = "isophase", True
    else:
        rhythm, mark = ("occulting", False) if duty > 0.5 else ("flashing", True)
    mark_floors = _floors(lit if mark else dark, dt)
    gaps = dark if mark else lit
    gap_floors = _floors(gaps, dt)
    top = len(gap_floors) - 1  # the longest gaps end groups; any between the shortest and those split composites
    # a gap the window cut is a long one once it outlasts every shorter gap seen whole: cutting only shortens
    shorter_max = max((g for g in gaps if _level(g, gap_floors) < top), default=-math.inf)
    groups: list[tuple[float, float, str, bool, bool]] = []  # (start, end, pattern, opened and closed by long gaps)
    start: float | None = None
    pattern, opened = "", False
    for i, (on, t0, d) in enumerate(runs):
        if on == mark:
            if start is None:
                start, pattern = t0, ""
            long = _level(d, mark_floors) > 0 or (rhythm == "flashing" and d >= LONG_MARK_S)
            pattern += "-" if long else "."
            continue
        if i in (0, len(runs) - 1):
            level = top if d > shorter_max + FRAME_SLACK * dt else -1  # -1: unknown
        else:
            level = _level(d, gap_floors)
        if level in (top, -1):
            if start is not None:
                groups.append((start, t0, pattern, opened, level == top))
            start, opened = None, level == top
        elif level > 0:
            pattern += "+"
    if start is not None:
        groups.append((start, math.inf, pattern, opened, False))
    whole = Counter(p for _, _, p, was_opened, closed in groups if was_opened and closed)
    # the period from the starts of groups seen to start, or from the ends of those seen to end: the more of them
    starts = [s for s, _, _, was_opened, _ in groups if was_opened]
    ends = [e for _, e, _, _, closed in groups if closed]
    times = max(starts, ends, key=len)
    if not whole or len(times) < 2:
        return "unreadable", "", None
    # a straight line through them, numbered by whole periods (a group lost to noise skips a number), averages
    # the placing of every run end it holds
    steps = np.maximum(1, np.round(np.diff(times) / np.median(np.diff(times))))
    period = float(np.polyfit(np.concatenate(([0], np.cumsum(steps))), times, 1)[0])
    return rhythm, whole.most_common(1)[0][0], period


def read_sequence(
    times_s: Sequence[float], on: Sequence[bool], colours: Sequence[str | None] | None = None
) -> ObservedLight:
    """The character frames show: times_s the frame times, on whether the light showed, colours its colour.

    A frame that disagrees with both its neighbours is taken as noise (a glint, a missed detection), not a phase:
    burst_for's rate gives every phase several frames. Frames may be missing and their times jittered; two
    flipped frames side by side, though, read as a phase of their own.
    """
    t = np.asarray(times_s, dtype=float)
    if t.shape != (len(on),) or len(t) < 3 or (colours is not None and len(colours) != len(t)):
        raise LightCharacterError("read_sequence needs three frames or more, with as many on flags (and colours)")
    order = np.argsort(t, kind="stable")
    t, raw = t[order], np.asarray(on, dtype=bool)[order]
    lit = raw.copy()
    # the majority of each frame and its two neighbours (at the ends: the first or last three)
    lit[1:-1] = (raw[:-2] & raw[1:-1]) | (raw[1:-1] & raw[2:]) | (raw[:-2] & raw[2:])
    lit[0], lit[-1] = raw[:3].sum() >= 2, raw[-3:].sum() >= 2
    seen: Counter[str] = Counter()
    if colours is not None:
        seen.update(c for c in (colours[i] for i in order[lit]) if c)
    common = tuple(c for c, n in seen.most_common() if n >= COLOUR_SHARE * seen.total())
    colour = common[0] if common else None
    if not lit.any():
        return ObservedLight("dark")
    if lit.all():
        return ObservedLight("fixed", colour=colour, colours=common)
    change = np.flatnonzero(lit[1:] != lit[:-1]) + 1  # the first frame of every run after the first
    ends = np.concatenate(([t[0]], (t[change - 1] + t[change]) / 2, [t[-1]]))  # a run ends between two frames
    runs = [(bool(lit[i]), float(a), float(b - a)) for i, a, b in zip((0, *change), ends[:-1], ends[1:], strict=True)]
    dt = float(np.median(np.diff(t)))
    rhythm, pattern, period = _structure(runs, dt)
    longest_dark = max((d for lit_run, _, d in runs if not lit_run), default=0.0)
    longest_lit = max((d for lit_run, _, d in runs if lit_run), default=0.0)
    return ObservedLight(rhythm, pattern, period, colour, common, longest_dark, longest_lit, dt)


def longest_phases(character: LightCharacter) -> tuple[float, float]:
    """(dark s, lit s): the longest the charted character stays dark and lit at a stretch (a colour change of an
    alternating light is no change of state)."""
    runs: list[tuple[bool, float]] = []
    for lit, d in character.phases() * 2:  # two periods: a phase that wraps round the period's end is whole
        if runs and runs[-1][0] == lit:
            runs[-1] = (lit, runs[-1][1] + d)
        else:
            runs.append((lit, d))
    return max((d for lit, d in runs if not lit), default=0.0), max((d for lit, d in runs if lit), default=0.0)


def outlasts_chart(charted: LightCharacter, observed: ObservedLight) -> bool:
    """Whether the light stayed dark or lit longer than the charted character ever does (beyond SPREAD and
    FRAME_SLACK frames): then it is not showing that character, whether or not its own rhythm could be read."""
    dark, lit = longest_phases(charted)
    slack = FRAME_SLACK * (observed.frame_interval_s or 0.0)
    too_long = [
        seen > (1 + SPREAD) * chart + slack
        for seen, chart in ((observed.longest_dark_s, dark), (observed.longest_lit_s, lit))
        if seen is not None and chart > 0
    ]
    return any(too_long)


def _expected(character: LightCharacter) -> tuple[str, str, float | None]:
    """(rhythm, pattern, period) that frames of the charted character read as: three periods, run by run."""
    runs: list[Run] = []
    t0 = 0.0
    for lit, d in character.phases() * 3:
        if runs and runs[-1][0] == lit:  # an alternating light changing colour, not state
            runs[-1] = (lit, runs[-1][1], runs[-1][2] + d)
        else:
            runs.append((lit, t0, d))
        t0 += d
    return ("fixed", "", None) if len(runs) == 1 else _structure(runs, 0.0)


def matches(charted: LightCharacter, observed: ObservedLight, period_tolerance: float = 0.1) -> list[str]:
    """How the observation differs from the chart: "light_out", "unreadable", "wrong_character", "wrong_period"
    (beyond period_tolerance, a fraction of the period), "wrong_colour"; an empty list when it matches."""
    if observed.rhythm == "dark":
        return ["light_out"]
    if observed.rhythm == "unreadable":  # no whole group: yet a dark or a flash longer than the chart's says enough
        return ["wrong_character"] if charted.kind != "F" and outlasts_chart(charted, observed) else ["unreadable"]
    rhythm, pattern, period = _expected(charted)
    findings = []
    if (observed.rhythm, observed.pattern) != (rhythm, pattern):
        findings.append("wrong_character")
    if period and observed.period_s and abs(observed.period_s - period) > period_tolerance * period:
        findings.append("wrong_period")
    if observed.colour is not None and (
        set(observed.colours) != set(charted.colours) if charted.alternating else observed.colour not in charted.colours
    ):
        findings.append("wrong_colour")
    return findings


SHORT_BURST = (2.0, 10.0)  # (s, Hz): enough frames to out-vote a few bad ones for a fixed or an unlit light
FRAMES_PER_PHASE = 4  # Nyquist's two frames per shortest phase, doubled for jitter and dropped frames
BURST_MARGIN_S = 1.0
MIN_BURST_S = 5.0  # a few cycles of a quick light at least: its period is then read to a few per cent
MIN_RATE_HZ = 10.0  # a video rate: a flipped frame is then a small part of even a long phase


def burst_for(character: LightCharacter | None) -> tuple[float, float]:
    """(duration s, rate Hz) a camera must capture to read the light (None: an unlit buoy).

    Two periods and a margin: whatever phase the burst starts in, it holds one group with a long dark on each
    side, and the start (or the end) of the groups either side of it; the rate gives the shortest light or dark
    FRAMES_PER_PHASE frames, and is never below MIN_RATE_HZ.
    """
    if character is None or (character.kind == "F" and not character.alternating):
        return SHORT_BURST
    phases = character.phases()
    period = math.fsum(d for _, d in phases)
    return max(MIN_BURST_S, 2 * period + BURST_MARGIN_S), max(MIN_RATE_HZ, FRAMES_PER_PHASE / min(d for _, d in phases))
