"""Frame selections: ``'1,3,5'``, ``'2:10'``, ``'4:'`` checked against a clip's length.

Ranges are half open (``'2:10'`` is frames 2 to 9) and checked before they are expanded, so a
selection costs memory in proportion to the clip, never to the numbers typed. The numbers are
the source's own (:mod:`stereodeblur.io.numbering`: KITTI 2015's frames 10 and 11); the
selection is returned as indices, counted from 0.
"""

from __future__ import annotations

import re

from ..errors import InputError

# Longest selection text accepted: far more than any hand-written list, small enough to parse.
MAX_TEXT = 10_000
# Most frames a selection that is not one range may list (it is expanded into a tuple).
MAX_LISTED = 10_000_000
_NUMBER = re.compile(r"[+-]?[0-9]{1,20}")


def _bound(text: str, value: str, default: int) -> int:
    value = value.strip()
    if not value:
        return default
    if not _NUMBER.fullmatch(value):
        raise InputError(f"frames {text!r}: {value!r} is not a frame number")
    return int(value)


def _parts(text: str, num_frames: int, first: int) -> list[range]:
    """The selection's pieces as ranges of indices, each number checked against
    ``first..first + num_frames - 1``."""
    end = first + num_frames
    last = end - 1
    pieces = []
    for part in text.split(","):
        if ":" in part:
            start_text, _, stop_text = part.partition(":")
            start = _bound(text, start_text, first)
            stop = _bound(text, stop_text, end)
            if not first <= start <= last or not start < stop <= end:
                raise InputError(
                    f"frames {text!r}: range {part.strip()!r} (end exclusive) must lie within "
                    f"{first}:{end}; the clip has frames {first}..{last}"
                )
            pieces.append(range(start - first, stop - first))
        else:
            if not part.strip():
                raise InputError(f"frames {text!r}: empty entry; give e.g. '1,3' or '2:10'")
            number = _bound(text, part, first - 1)
            if not first <= number <= last:
                raise InputError(f"frames {text!r}: frame {number} is not in {first}..{last}")
            pieces.append(range(number - first, number - first + 1))
    return pieces


def parse_frames(text: str | None, num_frames: int, *, first: int = 0) -> range | tuple[int, ...]:
    """Indices of the frames selected by ``text`` in a clip of ``num_frames`` frames whose
    first is numbered ``first``, sorted and unique.

    Parameters
    ----------
    text : str or None
        Comma-separated frame numbers and half-open ranges ``START:STOP`` (either end may be
        left out: ``'4:'`` is frame 4 to the last). None selects every frame.
    num_frames : int
        Frames in the clip.
    first : int
        The source's number of the clip's first frame (:mod:`stereodeblur.io.numbering`);
        ``text`` counts in these numbers.

    Returns
    -------
    range or tuple of int
        Indices (counted from 0): a ``range`` when the selection is contiguous, else a tuple.

    Raises
    ------
    InputError
        For text that is not a selection or a frame outside ``first..first + num_frames - 1``;
        the message names the text and the clip's frame numbers.
    """
    if isinstance(num_frames, bool) or not isinstance(num_frames, int) or num_frames < 1:
        raise InputError(f"the clip must have at least one frame, got num_frames={num_frames!r}")
    if isinstance(first, bool) or not isinstance(first, int) or first < 0:
        raise InputError(f"first must be an integer >= 0, got {first!r}")
    if text is None:
        return range(num_frames)
    if not isinstance(text, str):
        raise InputError(f"frames must be text like '1,3' or '2:10', got {type(text).__name__}")
    if len(text) > MAX_TEXT:
        raise InputError(f"frames: selection of {len(text)} characters, at most {MAX_TEXT}")
    pieces = sorted(_parts(text, num_frames, first), key=lambda r: r.start)
    merged = [pieces[0]]
    for piece in pieces[1:]:
        if piece.start <= merged[-1].stop:
            merged[-1] = range(merged[-1].start, max(merged[-1].stop, piece.stop))
        else:
            merged.append(piece)
    if len(merged) == 1:
        return merged[0]
    count = sum(len(piece) for piece in merged)
    if count > MAX_LISTED:
        raise InputError(
            f"frames {text!r}: selects {count} frames in {len(merged)} pieces; a selection that "
            f"is not one range may hold at most {MAX_LISTED}"
        )
    return tuple(index for piece in merged for index in piece)
