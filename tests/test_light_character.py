"""Navigation-light characters (uavcore.light_character): chart text in and out, the IALA timing conventions, and
reading a character back from sampled camera frames, noise included."""

import math

import numpy as np
import pytest

from uavcore.light_character import (
    LightCharacter,
    LightCharacterError,
    ObservedLight,
    burst_for,
    from_s57,
    matches,
    parse,
    read_sequence,
)

# The lights of the IALA buoys (lateral, cardinal, isolated danger, safe water, special, wreck) and a few more
# chart forms, each in canonical chart text: (text, kind, groups, colours, period s).
PARSED = [
    ("Fl(2) G 6s", "Fl", (2,), ("G",), 6.0),  # a starboard (region A) or port (region B) light
    ("Fl(2) W 5s", "Fl", (2,), ("W",), 5.0),  # isolated danger
    ("Q W", "Q", (), ("W",), None),  # north cardinal
    ("VQ W", "VQ", (), ("W",), None),
    ("Q(3) W 10s", "Q", (3,), ("W",), 10.0),  # east cardinal
    ("VQ(3) W 5s", "VQ", (3,), ("W",), 5.0),
    ("Q(6)+LFl W 15s", "Q+LFl", (6,), ("W",), 15.0),  # south cardinal
    ("VQ(6)+LFl W 10s", "VQ+LFl", (6,), ("W",), 10.0),
    ("Q(9) W 15s", "Q", (9,), ("W",), 15.0),  # west cardinal
    ("VQ(9) W 10s", "VQ", (9,), ("W",), 10.0),
    ("Iso W 4s", "Iso", (), ("W",), 4.0),  # safe water
    ("Oc W 5s", "Oc", (), ("W",), 5.0),
    ("LFl W 10s", "LFl", (), ("W",), 10.0),
    ("Fl Y 5s", "Fl", (), ("Y",), 5.0),  # special
    ("F Y", "F", (), ("Y",), None),
    ("Fl(2+1) R 10s", "Fl", (2, 1), ("R",), 10.0),  # preferred channel
    ("Oc(2+1) G 12s", "Oc", (2, 1), ("G",), 12.0),
    ("Oc(2) G 8s", "Oc", (2,), ("G",), 8.0),
    ("Iso R 4s", "Iso", (), ("R",), 4.0),
    ("Oc G 5s", "Oc", (), ("G",), 5.0),
    ("UQ W", "UQ", (), ("W",), None),
    ("IQ W 10s", "IQ", (), ("W",), 10.0),
    ("IVQ W 5s", "IVQ", (), ("W",), 5.0),
    ("Fl W 2.5s", "Fl", (), ("W",), 2.5),
    ("Al.Fl WR 4s", "Fl", (), ("W", "R"), 4.0),
    ("Al.BuY 3s", "F", (), ("Bu", "Y"), 3.0),  # emergency wreck marking
    ("Mo(A) W 6s", "Mo", (), ("W",), 6.0),  # safe water
]
TEXTS = [text for text, *_ in PARSED]
PERIODIC = [text for text in TEXTS if parse(text).cycle_s is not None]


@pytest.mark.parametrize(("text", "kind", "groups", "colours", "period_s"), PARSED)
def test_parse_reads_class_group_colours_and_period(text, kind, groups, colours, period_s):
    c = parse(text)
    assert (c.kind, c.groups, c.colours, c.period_s) == (kind, groups, colours, period_s)


def test_parse_reads_morse_letters_and_alternating_colours():
    assert parse("Mo(A) W 6s").morse == "A"
    assert parse("Al.WR") == parse("Al WR") == LightCharacter("F", (), ("W", "R"), None, alternating=True)
    assert parse("Al.Fl WR 4s").alternating


@pytest.mark.parametrize("text", ["Fl(2)G.6s", "fl(2) g 6S", "FL (2) G. 6 s", "Fl.(2).G.6sec", "  Fl(2)  G  6s. "])
def test_parse_tolerates_case_spacing_and_dots_as_chart_text_has_them(text):
    assert parse(text) == parse("Fl(2) G 6s")


def test_a_colour_left_out_is_white_as_on_charts():
    assert parse("Fl 5s").colours == ("W",)


@pytest.mark.parametrize("text", TEXTS)
def test_abbreviation_is_the_canonical_text_and_parses_back_to_the_same_character(text):
    c = parse(text)
    assert c.abbreviation() == text
    assert parse(c.abbreviation()) == c


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "empty light character"),
        ("Xy W 5s", r"no light class at 'Xy W 5s'"),
        ("Fl(x) G 6s", r"cannot read the group 'x'"),
        ("Fl(2 G 6s", r"cannot read '\(2 G 6s'"),
        ("Fl(2) P 6s", r"cannot read 'P 6s'.*expected colours"),
        ("Fl G 6s 5M", r"cannot read '5M'"),
        ("Fl(2)+LFl W 15s", r"\+LFl follows only Q, VQ or UQ, not Fl"),
        ("Iso(2) W 4s", r"Iso takes no group"),
        ("Mo W 6s", r"Mo needs its Morse letters"),
        ("Al.W", r"alternating light needs two colours"),
        ("Fl G 0s", r"period must be positive"),
        ("Q(9) W 5s", r"Q\(9\) W 5s: its group lasts 8.3 s, too long for a 5 s period"),
    ],
)
def test_bad_text_raises_a_light_character_error_naming_what_could_not_be_read(text, message):
    with pytest.raises(LightCharacterError, match=message):
        parse(text)
    assert issubclass(LightCharacterError, ValueError)


def test_a_class_without_a_charted_period_has_no_phases():
    with pytest.raises(LightCharacterError, match="no period charted, and Fl implies none"):
        parse("Fl R").phases()


@pytest.mark.parametrize("text", PERIODIC)
def test_phases_alternate_from_the_groups_first_mark_and_sum_to_the_period_exactly(text):
    c = parse(text)
    phases = c.phases()
    assert math.fsum(d for _, d in phases) == c.cycle_s
    assert all(d > 0 for _, d in phases)
    assert phases[0][0] is (c.kind != "Oc")  # phase 0: a group's first flash, or an occulting light's eclipse


@pytest.mark.parametrize(("text", "per_minute"), [("Q W", 60), ("VQ W", 120), ("UQ W", 240)])
def test_quick_classes_flash_at_their_iala_rate(text, per_minute):
    c = parse(text)
    assert 60 / c.cycle_s == pytest.approx(per_minute)
    (_, flash), (_, dark) = c.phases()
    assert flash < dark


# Morse keeps its own timing: a dot lasts as long as the gap after it
@pytest.mark.parametrize("text", [t for t in PERIODIC if parse(t).kind not in ("F", "Iso", "Oc", "Mo")])
def test_every_flash_is_shorter_than_the_dark_after_it(text):
    phases = parse(text).phases()
    assert all(flash < dark for (_, flash), (_, dark) in zip(phases[::2], phases[1::2], strict=True))


@pytest.mark.parametrize("text", ["LFl W 10s", "Q(6)+LFl W 15s", "VQ(6)+LFl W 10s"])
def test_a_long_flash_lasts_at_least_two_seconds(text):
    assert max(d for on, d in parse(text).phases() if on) >= 2.0


def test_isophase_light_and_dark_are_equal_and_occulting_light_outlasts_the_dark():
    assert parse("Iso R 4s").phases() == [(True, 2.0), (False, 2.0)]
    for text in ("Oc G 5s", "Oc(2) G 8s", "Oc(2+1) G 12s"):
        phases = parse(text).phases()
        assert sum(d for on, d in phases if on) > sum(d for on, d in phases if not on)


def test_the_typical_durations_are_those_documented():
    assert parse("Fl(2) G 6s").phases() == [(True, 0.5), (False, 1.0), (True, 0.5), (False, 4.0)]
    assert parse("Mo(A) W 6s").phases() == [(True, 0.5), (False, 0.5), (True, 1.5), (False, 3.5)]
    assert parse("LFl W 10s").phases() == [(True, 2.0), (False, 8.0)]
    south = parse("Q(6)+LFl W 15s").phases()
    assert south[:2] == [(True, 0.3), (False, 0.7)] and south[-2:] == [(True, 2.0), (False, pytest.approx(7.0))]


def test_a_group_shrinks_to_fit_a_short_period_and_leaves_the_long_dark_last():
    phases = parse("Fl(4) Y 6s").phases()
    assert math.fsum(d for _, d in phases[:-1]) == pytest.approx(0.45 * 6)
    assert phases[-1][1] > max(d for _, d in phases[:-1])


def test_is_on_follows_the_phases_at_any_time():
    c = parse("Fl(2) G 6s")
    assert [c.is_on(t) for t in (0.25, 0.75, 1.75, 3.0, 5.9)] == [True, False, True, False, False]
    assert c.is_on(6.25) and c.is_on(600.25) and c.is_on(-5.75)  # periodic, before 0 too
    assert parse("F Y").is_on(1234.5)


def test_an_alternating_light_takes_its_colours_in_turn():
    c = parse("Al.Fl WR 4s")
    assert [c.colour_at(t) for t in (0.25, 1.0, 2.25, 4.25)] == ["W", None, "R", "W"]
    fixed = parse("Al.WR 6s")
    assert [fixed.colour_at(t) for t in (1.0, 4.0)] == ["W", "R"] and fixed.is_on(4.0)
    assert parse("Fl(2) G 6s").colour_at(0.25) == "G"


def frames(character, start_s=0.0, rate_hz=None, flip=False, drop=False, jitter=0.25, seed=0):
    """Frames of the charted light over burst_for's duration (at its rate unless given): their times, jittered by
    up to `jitter` of an interval, whether lit, and the colour; one frame flipped and one lost if asked."""
    duration_s, burst_rate = burst_for(character)
    rate = rate_hz or burst_rate
    rng = np.random.default_rng(seed)
    n = int(duration_s * rate)
    times = start_s + (np.arange(n) + rng.uniform(-jitter, jitter, n)) / rate
    on = [character.is_on(t) for t in times]
    colours = [character.colour_at(t) for t in times]
    if flip:
        on[n // 3] = not on[n // 3]
    keep = [i for i in range(n) if not (drop and i == 2 * n // 3)]
    return [times[i] for i in keep], [on[i] for i in keep], [colours[i] for i in keep]


# what frames of each light read as: (text, rhythm, groups, pattern)
READINGS = [
    ("Fl(2) G 6s", "flashing", (2,), ".."),
    ("Fl(2) W 5s", "flashing", (2,), ".."),
    ("Q W", "flashing", (1,), "."),
    ("VQ W", "flashing", (1,), "."),
    ("UQ W", "flashing", (1,), "."),
    ("Q(3) W 10s", "flashing", (3,), "..."),
    ("VQ(3) W 5s", "flashing", (3,), "..."),
    ("Q(6)+LFl W 15s", "flashing", (7,), "......-"),
    ("VQ(6)+LFl W 10s", "flashing", (7,), "......-"),
    ("Q(9) W 15s", "flashing", (9,), "........."),
    ("VQ(9) W 10s", "flashing", (9,), "........."),
    ("Iso R 4s", "isophase", (1,), "."),
    ("Oc G 5s", "occulting", (1,), "."),
    ("Oc(2) G 8s", "occulting", (2,), ".."),
    ("Oc(2+1) G 12s", "occulting", (2, 1), "..+."),
    ("LFl W 10s", "flashing", (1,), "-"),
    ("Fl Y 5s", "flashing", (1,), "."),
    ("Fl W 2.5s", "flashing", (1,), "."),
    ("Fl(2+1) R 10s", "flashing", (2, 1), "..+."),
    ("Mo(A) W 6s", "flashing", (2,), ".-"),
    ("IQ W 10s", "flashing", (7,), "......."),
    ("Al.Fl WR 4s", "flashing", (1,), "."),
]


@pytest.mark.parametrize("start", [0.0, 0.37, 0.81])
@pytest.mark.parametrize(("text", "rhythm", "groups", "pattern"), READINGS)
def test_frames_of_a_charted_light_read_back_as_its_character(text, rhythm, groups, pattern, start):
    c = parse(text)
    turns = len(c.colours) if c.alternating else 1
    times, on, colours = frames(c, start_s=start * c.cycle_s, flip=True, drop=True, seed=round(100 * start))
    observed = read_sequence(times, on, colours)
    assert (observed.rhythm, observed.groups, observed.pattern) == (rhythm, groups, pattern)
    assert observed.period_s == pytest.approx(c.cycle_s / turns, rel=0.03)
    assert set(observed.colours) == set(c.colours)
    assert matches(c, observed) == []


@pytest.mark.parametrize("text", ["Fl(2) G 6s", "Q(6)+LFl W 15s", "Mo(A) W 6s", "Oc(2) G 8s"])
def test_a_faster_camera_reads_the_same(text):
    c = parse(text)
    assert matches(c, read_sequence(*frames(c, start_s=1.3, rate_hz=30.0, flip=True, drop=True))) == []


def test_a_dark_light_and_a_fixed_one_read_as_such_despite_a_flipped_frame():
    times = [i / 10 for i in range(20)]
    assert read_sequence(times, [i == 7 for i in range(20)]).rhythm == "dark"
    fixed = read_sequence(times, [i != 7 for i in range(20)], ["Y"] * 20)
    assert (fixed.rhythm, fixed.colour) == ("fixed", "Y")
    assert matches(parse("F Y"), fixed) == []
    assert matches(parse("Al.WR 6s"), read_sequence(*frames(parse("Al.WR 6s")))) == []


def test_matches_reports_a_light_out_and_a_wrong_character():
    charted = parse("Fl(2) G 6s")
    assert matches(charted, ObservedLight("dark")) == ["light_out"]
    three = read_sequence(*frames(parse("Fl(3) G 6s"), flip=True))
    assert three.groups == (3,)
    assert matches(charted, three) == ["wrong_character"]
    assert matches(parse("F Y"), read_sequence(*frames(parse("Fl Y 5s")))) == ["wrong_character"]
    assert matches(charted, read_sequence(*frames(parse("Iso G 6s")))) == ["wrong_character"]


def test_matches_reports_a_wrong_period_and_a_wrong_colour():
    charted = parse("Fl(2) G 6s")
    assert matches(charted, read_sequence(*frames(parse("Fl(2) G 8s")))) == ["wrong_period"]
    assert matches(charted, read_sequence(*frames(parse("Fl(2) R 6s")))) == ["wrong_colour"]
    one_colour = read_sequence(*frames(parse("Fl W 2s")))
    assert matches(parse("Al.Fl WR 4s"), one_colour) == ["wrong_colour"]
    assert matches(parse("Fl(2) W 5s"), read_sequence(*frames(charted))) == ["wrong_period", "wrong_colour"]


def test_the_period_tolerance_is_a_fraction_of_the_charted_period():
    observed = ObservedLight("flashing", "..", 6.4, "G", ("G",))
    assert matches(parse("Fl(2) G 6s"), observed) == []
    assert matches(parse("Fl(2) G 6s"), observed, period_tolerance=0.05) == ["wrong_period"]


def test_too_short_a_sequence_is_unreadable_not_a_finding_about_the_light():
    c = parse("Fl(2) G 6s")
    times = [i / 10 for i in range(40)]
    observed = read_sequence(times, [c.is_on(t) for t in times])
    assert observed.rhythm == "unreadable"
    assert matches(c, observed) == ["unreadable"]


def test_read_sequence_refuses_frames_that_do_not_line_up():
    with pytest.raises(LightCharacterError, match="three frames or more"):
        read_sequence([0.0, 0.1, 0.2], [True, False])
    with pytest.raises(LightCharacterError, match="three frames or more"):
        read_sequence([0.0, 0.1], [True, False])


@pytest.mark.parametrize("text", [t for t in PERIODIC if parse(t).kind != "F"])
def test_a_burst_covers_two_periods_and_resolves_the_shortest_phase(text):
    c = parse(text)
    duration_s, rate_hz = burst_for(c)
    assert duration_s >= 2 * c.cycle_s + 1.0
    assert rate_hz >= 2 * 2 / min(d for _, d in c.phases())  # Nyquist's two frames per phase, twice over


def test_a_fixed_or_unlit_light_needs_only_a_short_burst():
    assert burst_for(parse("F Y")) == burst_for(None)
    assert burst_for(None)[0] <= 2.0
    with pytest.raises(LightCharacterError, match="no period"):
        burst_for(parse("Al.WR"))  # the colour changes, but the chart does not say how often


@pytest.mark.parametrize(
    ("litchr", "siggrp", "sigper", "colour", "text"),
    [
        (2, "(2)", 6.0, "4", "Fl(2) G 6s"),
        (2, "(1)", 2.5, "3", "Fl R 2.5s"),  # NOAA's cells give a single flash its group of one
        (7, "(1)", 6.0, "1", "Iso W 6s"),  # ... and isophase, which takes no group
        (25, "(6)", 15.0, "1", "Q(6)+LFl W 15s"),
        (4, "()", None, "1", "Q W"),
        (12, "(A)", 6.0, "1", "Mo(A) W 6s"),
        (7, "", 4.0, "3", "Iso R 4s"),
        (28, "", None, "1,3", "Al.WR"),
        (19, "", 4.0, "1,3", "Al.Fl WR 4s"),
    ],
)
def test_from_s57_reads_the_lights_attributes(litchr, siggrp, sigper, colour, text):
    assert from_s57(litchr, siggrp, sigper, colour) == parse(text)


def test_from_s57_refuses_codes_it_does_not_read():
    with pytest.raises(LightCharacterError, match="LITCHR 13"):
        from_s57(13, "", 5.0, "1")
    with pytest.raises(LightCharacterError, match="COLOUR '2'"):
        from_s57(2, "", 5.0, "2")


def burst_of(shows: LightCharacter, sized_for: LightCharacter, start_s: float) -> ObservedLight:
    """What a burst sized for one character (burst_for) reads of a light showing another, from start_s."""
    duration_s, rate_hz = burst_for(sized_for)
    times = [start_s + k / rate_hz for k in range(math.ceil(duration_s * rate_hz))]
    return read_sequence(times, [shows.is_on(t) for t in times])


@pytest.mark.parametrize(
    "charted, shows", [("Fl R 4s", "Fl R 8s"), ("Fl G 4s", "Fl G 10s"), ("Fl(2) W 5s", "Fl(2) W 12s")]
)
def test_a_light_slower_than_charted_is_a_wrong_character_even_where_the_burst_is_too_short_to_read_it(charted, shows):
    """The burst covers two of the charted periods: a light whose period is twice that or more shows at most one
    group in it, which cannot be read, but its darks outlast the chart's longest: it is not the charted light (and
    where no flash fell in the burst at all, it is seen out). Never "unreadable": the buoy is a defect either way."""
    for start_s in np.linspace(0.0, 12.0, 25):
        observed = burst_of(parse(shows), parse(charted), float(start_s))
        found = matches(parse(charted), observed)
        expected = {"light_out"} if observed.rhythm == "dark" else {"wrong_character", "wrong_period"}
        assert found and set(found) <= expected, (start_s, observed, found)


@pytest.mark.parametrize(
    "text",
    [
        "Fl R 4s",
        "Fl(2) G 6s",
        "Q(3) W 10s",
        "Q(6)+LFl W 15s",
        "Q(9) W 15s",
        "LFl W 10s",
        "Iso W 4s",
        "Oc G 5s",
        "Mo(A) W 8s",
        "VQ W",
        "Q W",
        "Fl(2+1) R 6s",
    ],
)
def test_a_light_showing_its_charted_character_is_never_taken_for_another(text):
    """No false alarm from the longest-phase test: the charted light in its own burst, from any phase, matches."""
    c = parse(text)
    for start_s in np.linspace(0.0, c.period_s or 1.0, 17):
        assert matches(c, burst_of(c, c, float(start_s))) == [], (text, start_s)
