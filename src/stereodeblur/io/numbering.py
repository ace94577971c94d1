"""How a source numbers and names its frames, so results keep the input's names.

Conventions
-----------
Code counts a clip's frames by *index*, ``0 .. num_frames - 1``. The user sees the source's
own *numbers* and *names*: index ``i`` is number ``first + i``, named ``prefix`` followed by
the number padded to ``digits`` digits. A scene folder (and a video pair) numbers from 0 with
six digits (``000000``); KITTI 2012/2015 names frame 10 of sequence 5 ``000005_10`` (numbers
10, 11, ...); a KITTI raw drive numbers from 0 with ten digits (``0000000042``).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import InputError


@dataclass(frozen=True)
class FrameNumbering:
    """Frame ``index`` is number ``first + index``, named ``prefix`` + the padded number.

    Parameters
    ----------
    first : int
        Number of the clip's first frame (>= 0).
    digits : int
        Digits of the number in a name, zero-padded (>= 1).
    prefix : str
        What comes before the number in a name (e.g. KITTI's sequence, ``'000005_'``).
    """

    first: int = 0
    digits: int = 6
    prefix: str = ""

    def __post_init__(self):
        if isinstance(self.first, bool) or not isinstance(self.first, int) or self.first < 0:
            raise InputError(f"first must be an integer >= 0, got {self.first!r}")
        if isinstance(self.digits, bool) or not isinstance(self.digits, int) or self.digits < 1:
            raise InputError(f"digits must be an integer >= 1, got {self.digits!r}")
        if not isinstance(self.prefix, str) or "/" in self.prefix or "\0" in self.prefix:
            raise InputError(f"prefix must be text without '/', got {self.prefix!r}")

    def number(self, index: int) -> int:
        """The source's number of frame ``index``."""
        return self.first + int(index)

    def index(self, number: int) -> int:
        """The index of the frame the source numbers ``number``."""
        return int(number) - self.first

    def name(self, index: int) -> str:
        """The file name (without extension) of frame ``index``, e.g. ``'000005_10'``."""
        return f"{self.prefix}{self.number(index):0{self.digits}d}"


# Scene folders and video pairs: 000000, 000001, ...
SCENE_NUMBERING = FrameNumbering()
