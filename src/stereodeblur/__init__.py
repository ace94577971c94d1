"""Motion deblurring of rectified stereo video (Sellent, Rother, Roth, ECCV 2016)."""

__version__ = "0.1.0"
