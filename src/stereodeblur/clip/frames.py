"""Frame selections: ``'1,3,5'``, ``'2:10'``, ``'4:'`` checked against a clip's length.

Ranges are half open (``'2:10'`` is frames 2 to 9) and checked before they are expanded, so a
selection costs memory in proportion to the clip, never to the numbers typed.
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


def _parts(text: str, num_frames: int) -> list[range]:
    """The selection's pieces as ranges, each checked against ``0..num_frames - 1``."""
    last = num_frames - 1
    pieces = []
    for part in text.split(","):
        if ":" in part:
            start_text, _, stop_text = part.partition(":")
            start = _bound(text, start_text, 0)
            stop = _bound(text, stop_text, num_frames)
            if not 0 <= start <= last or not start < stop <= num_frames:
                raise InputError(
                    f"frames {text!r}: range {part.strip()!r} (end exclusive) must lie within "
                    f"0:{num_frames}; the clip has frames 0..{last}"
                )
            pieces.append(range(start, stop))
        else:
            if not part.strip():
                raise InputError(f"frames {text!r}: empty entry; give e.g. '1,3' or '2:10'")
            index = _bound(text, part, -1)
            if not 0 <= index <= last:
                raise InputError(f"frames {text!r}: frame {index} is not in 0..{last}")
            pieces.append(range(index, index + 1))
    return pieces


def parse_frames(text: str | None, num_frames: int) -> range | tuple[int, ...]:
    """Frames selected by ``text`` in a clip of ``num_frames`` frames, sorted and unique.

    Parameters
    ----------
    text : str or None
        Comma-separated frame numbers and half-open ranges ``START:STOP`` (either end may be
        left out: ``'4:'`` is frame 4 to the last). None selects every frame.
    num_frames : int
        Frames in the clip.

    Returns
    -------
    range or tuple of int
        A ``range`` when the selection is contiguous, else a tuple.

    Raises
    ------
    InputError
        For text that is not a selection or a frame outside ``0..num_frames - 1``; the
        message names the text and the clip's frame range.
    """
    if isinstance(num_frames, bool) or not isinstance(num_frames, int) or num_frames < 1:
        raise InputError(f"the clip must have at least one frame, got num_frames={num_frames!r}")
    if text is None:
        return range(num_frames)
    if not isinstance(text, str):
        raise InputError(f"frames must be text like '1,3' or '2:10', got {type(text).__name__}")
    if len(text) > MAX_TEXT:
        raise InputError(f"frames: selection of {len(text)} characters, at most {MAX_TEXT}")
    pieces = sorted(_parts(text, num_frames), key=lambda r: r.start)
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
