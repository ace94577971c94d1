"""Property-based fuzzing of the runner's parsers: on arbitrary input each returns a valid
value or raises InputError, never anything else."""

import json

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stereodeblur.clip import parse_frames, parse_run_log, read_run_log
from stereodeblur.errors import InputError

FUZZ = settings(max_examples=300, deadline=None)

# Text made of the selection's own characters, so that valid selections come up often.
selection_text = st.text(alphabet="0123456789:,+- \t_x\u0663", max_size=40)
event = st.fixed_dictionaries(
    {"event": st.sampled_from(["start", "frame", "end"])},
    optional={"index": st.integers(), "view": st.text(max_size=5)},
)


def _valid_selection(frames, num_frames):
    assert isinstance(frames, range | tuple)
    if isinstance(frames, range):  # never expanded: it may be long
        assert frames.step == 1 and 0 <= frames.start < frames.stop <= num_frames
        return
    assert frames and list(frames) == sorted(set(frames))
    assert 0 <= frames[0] and frames[-1] < num_frames


@FUZZ
@given(text=st.one_of(selection_text, st.text(max_size=40)), num_frames=st.integers(-5, 10**12))
def test_parse_frames_returns_a_selection_or_raises_input_error(text, num_frames):
    try:
        frames = parse_frames(text, num_frames)
    except InputError as error:
        assert "\n" not in str(error)
        return
    _valid_selection(frames, num_frames)


@FUZZ
@given(value=st.one_of(st.none(), st.integers(), st.floats(), st.binary(), st.lists(st.integers())))
def test_parse_frames_of_other_values(value):
    try:
        frames = parse_frames(value, 7)
    except InputError:
        return
    _valid_selection(frames, 7)


@FUZZ
@given(data=st.binary(max_size=400))
def test_run_log_of_arbitrary_bytes(data):
    contents = parse_run_log(data)
    assert all(isinstance(e, dict) and isinstance(e["event"], str) for e in contents.events)
    assert all(isinstance(p, str) for p in contents.problems)


@FUZZ
@given(
    events=st.lists(event, max_size=5),
    junk=st.lists(st.binary(max_size=30), max_size=4),
    cut=st.integers(0, 50),
)
def test_run_log_keeps_every_whole_event(events, junk, cut):
    lines = [json.dumps(e).encode() for e in events]
    data = b"\n".join(lines + [j.replace(b"\n", b"") for j in junk])
    contents = parse_run_log(data[: len(data) - cut] if cut < len(data) else data)
    whole = [json.loads(line) for line in lines if len(b"\n".join(lines)) <= len(data) - cut]
    for item in whole:
        assert item in contents.events


@settings(
    max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.binary(max_size=200))
def test_read_run_log_of_a_damaged_file(tmp_path, data):
    path = tmp_path / "run-log.jsonl"
    path.write_bytes(data)
    try:
        contents = read_run_log(path)
    except InputError:
        return
    assert isinstance(contents.events, tuple)
