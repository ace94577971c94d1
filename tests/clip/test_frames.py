"""Frame selections (stereodeblur.clip.frames.parse_frames)."""

import pytest

from stereodeblur.clip.frames import parse_frames
from stereodeblur.errors import InputError


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (None, range(10)),
        ("3", range(3, 4)),
        ("2:5", range(2, 5)),
        ("7:", range(7, 10)),
        (":2", range(0, 2)),
        ("0:3,2:6", range(0, 6)),
        ("5,1,3,1", (1, 3, 5)),
        (" 1 , 8: ", (1, 8, 9)),
    ],
)
def test_selections(text, expected):
    frames = parse_frames(text, 10)
    assert frames == expected
    assert isinstance(frames, range | tuple)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("0:100000000000", r"within 0:10; the clip has frames 0\.\.9"),
        ("10", r"frame 10 is not in 0\.\.9"),
        ("-1", r"frame -1 is not in 0\.\.9"),
        ("4:2", "within 0:10"),
        ("x", "'x' is not a frame number"),
        ("1,,2", "empty entry"),
        ("", "empty entry"),
        ("9" * 5000, "not a frame number"),
        ("1:2:3", "not a frame number"),
    ],
)
def test_bad_selections_are_one_line_input_errors(text, message):
    with pytest.raises(InputError, match=message) as caught:
        parse_frames(text, 10)
    assert "\n" not in str(caught.value)


def test_huge_range_is_checked_before_it_is_expanded():
    assert parse_frames("0:", 10**15) == range(10**15)  # a range, not a list
    with pytest.raises(InputError, match="within"):
        parse_frames("0:100000000000", 10)


@pytest.mark.parametrize("num_frames", [0, -3, 2.5, True, "7"])
def test_bad_clip_length(num_frames):
    with pytest.raises(InputError, match="at least one frame"):
        parse_frames("0", num_frames)


def test_long_selection_of_several_pieces_is_refused_before_it_is_expanded():
    assert parse_frames("0:3,5:8", 10**15) == (0, 1, 2, 5, 6, 7)
    with pytest.raises(InputError, match="at most 10000000"):
        parse_frames("0:3,5:", 10**15)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (None, range(3)),
        ("10", range(0, 1)),
        ("11:", range(1, 3)),
        (":12", range(0, 2)),
        ("12,10", (0, 2)),
    ],
)
def test_selections_count_in_the_sources_numbers(text, expected):
    """A clip numbered from 10 (KITTI 2015's frames 10, 11, 12): numbers in, indices out."""
    assert parse_frames(text, 3, first=10) == expected


@pytest.mark.parametrize(
    ("text", "message"),
    [("0", "frame 0 is not in 10..12"), ("9:11", "within 10:13; the clip has frames 10..12")],
)
def test_numbers_outside_the_sources_are_refused(text, message):
    with pytest.raises(InputError, match=message):
        parse_frames(text, 3, first=10)
