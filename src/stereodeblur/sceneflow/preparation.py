"""The four frames as the scene-flow stages use them: grey, one common gain, census codes.

Stage 1 of :func:`~stereodeblur.sceneflow.estimate.estimate_scene_flow`. The frames
are left t, right t, left t + 1, right t + 1 (this order everywhere), float in [0, 1],
grey or RGB.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .census import census_descriptors, shot_noise_flattens_the_dark
from .initial import to_gray, to_gray_u8
from .settings import SceneFlowSettings

__all__ = ["PreparedFrames", "census_encoding", "matching_encoding", "prepare_frames"]

MIN_CONTRAST = 2.0 / 255.0  # grey-level std below which a frame counts as textureless


@dataclass(frozen=True)
class PreparedFrames:
    """The four frames in the forms the stages need.

    Attributes
    ----------
    grays : tuple of 4 ndarray, (H, W) float32
        Grey frames as given.
    gain : float
        Common gain that takes the brightest of them to the full range.
    normed : tuple of 4 ndarray, (H, W) float32
        ``grays * gain`` clipped to [0, 1].
    u8 : tuple of 4 ndarray, (H, W) uint8
        8-bit versions of ``normed ** matching_gamma`` for OpenCV's matchers.
    codes : tuple of 4 ndarray
        Census descriptors (:func:`census.census_descriptors`).
    segment_image : ndarray, (H, W) or (H, W, 3) float64
        The left frame at t for the superpixels (colour if given, with the gain).
    contrast_ok : bool
        Whether every frame has some texture.
    messages : tuple of str
        Problems with the input (textureless, identical frames or views).
    other_side_codes : tuple of 2 ndarray or None
        Census descriptors of left and right on the other side of t, with the same gain, if
        given.
    census_gamma : float
        The census's encoding (:func:`census_encoding`).
    """

    grays: tuple[np.ndarray, ...]
    gain: float
    normed: tuple[np.ndarray, ...]
    u8: tuple[np.ndarray, ...]
    codes: tuple[np.ndarray, ...]
    segment_image: np.ndarray
    contrast_ok: bool
    messages: tuple[str, ...]
    other_side_codes: tuple[np.ndarray, ...] | None = None
    census_gamma: float = 1.0


def matching_encoding(gray: np.ndarray, gamma: float) -> np.ndarray:
    """``gray ** gamma``: linear grey in [0, 1] encoded for matching (census, SGBM, DIS).

    Linear light rounded to 8 bits leaves a deep shadow a handful of levels (a road in
    shade at 0.03 of full scale: 8 levels), too few for SGBM and DIS; the square root
    spreads the dark levels (that road: 44 levels) as a camera's encoding does, and makes
    shot noise about equally strong at every brightness.
    """
    if gamma == 1.0:
        return gray
    return np.power(np.clip(gray, 0.0, None), np.float32(gamma), dtype=np.float32)


def census_encoding(gray: np.ndarray, settings: SceneFlowSettings) -> float:
    """The power the census compares: ``settings.census_gamma``, or if that is None, 0.5
    where shot noise would flatten the dark parts of ``gray`` in linear light
    (:func:`~.census.shot_noise_flattens_the_dark`), else 1."""
    if settings.census_gamma is not None:
        return settings.census_gamma
    flattened = shot_noise_flattens_the_dark(
        gray, threshold=settings.census_threshold, noise_factor=settings.census_noise_factor
    )
    return 0.5 if flattened else 1.0


def prepare_frames(images, settings: SceneFlowSettings, other_side=None) -> PreparedFrames:
    """Grey frames with a common gain (dark inputs use the full 8-bit range) and census codes.

    Census "similar" bands are relative to the brightness (dark texture counts) and above
    the sensor noise (estimated on each frame); noisy frames are smoothed first.
    ``other_side``: left and right on the other side of t, for their census codes only.
    """
    grays = [to_gray(np.asarray(im, dtype=np.float32)) for im in images]
    top = max(float(np.percentile(g, 99.5)) for g in grays)
    gain = 1.0 / top if top > 1e-3 else 1.0
    gain = min(gain, settings.max_gain)

    def normalised(gray):
        return np.clip(gray * np.float32(gain), 0.0, 1.0)

    normed = [normalised(g) for g in grays]
    u8 = [to_gray_u8(matching_encoding(g, settings.matching_gamma)) for g in normed]

    gamma = census_encoding(normed[0], settings)

    def codes_of(gray):
        return census_descriptors(
            matching_encoding(gray, gamma),
            threshold=settings.census_threshold,
            noise_factor=settings.census_noise_factor,
            denoise=settings.census_denoise,
            relative=gamma == 1.0,
        )

    codes = tuple(codes_of(g) for g in normed)
    other_codes = None
    if other_side is not None:
        other = (to_gray(np.asarray(im, dtype=np.float32)) for im in other_side)
        other_codes = tuple(codes_of(normalised(g)) for g in other)
    messages = []
    contrast = [float(np.std(g)) for g in normed]
    contrast_ok = min(contrast) >= MIN_CONTRAST
    if not contrast_ok:
        messages.append(
            "input frames are (nearly) textureless (grey-level std "
            f"{min(contrast) * 255:.2f}/255): planes and motions are guesses"
        )
    if np.array_equal(u8[0], u8[2]) and np.array_equal(u8[1], u8[3]):
        messages.append("frames t and t+1 are identical: the estimated motion is zero")
    if np.array_equal(u8[0], u8[1]):
        messages.append("left and right views are identical: zero disparity, depth unknown")
    segment_image = np.asarray(images[0], dtype=np.float64)
    if segment_image.ndim == 3 and segment_image.shape[2] == 3:
        segment_image = np.clip(segment_image * gain, 0, 1)
    else:
        segment_image = normed[0].astype(np.float64)
    return PreparedFrames(
        grays=tuple(grays),
        gain=float(gain),
        normed=tuple(normed),
        u8=tuple(u8),
        codes=codes,
        segment_image=segment_image,
        contrast_ok=contrast_ok,
        messages=tuple(messages),
        other_side_codes=other_codes,
        census_gamma=gamma,
    )
