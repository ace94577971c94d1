"""Deblur one stereo frame: orchestration of motion, blur operator and deconvolution.

The stages, each a function from typed values to a typed value:

1. :func:`read_window`: the :class:`FrameWindow`, every frame the stereo frame's
   deblurring needs, each read once; :func:`estimate_exposure`: the exposure from the
   frames (``exposure='auto'``), or the check of the given one (:func:`exposure_doubt`);
2. :func:`stereo_motion`: the :class:`StereoMotion`, computed once for both views;
3. :func:`view_operator`: a view's blur operator (:class:`ViewOperator`);
4. :func:`data_terms`: its data weights, anchor, trust and prior weight
   (:class:`DataTerms`);
5. :func:`solve`: the deconvolution of Eq. 6.

:func:`deblur_stereo_frame` runs them for both views, :func:`deblur_frame` for one.
Frame i is deblurred with the motion from frame i to i + 1; the last frame of a clip uses
the motion to frame i - 1 (:func:`neighbour_of`). Motion sources are orthogonal to kernel
types, so every variant of the paper's tables is a combination of ``motion_source`` and
``kernels`` (:class:`DeblurSettings`):

- ``motion_source='sceneflow'`` (default): piecewise-rigid scene flow estimated from the
  blurred stereo frames (left view; the right view's by :func:`to_right_view`); 2D
  displacements are its projection. The views' dense optical flow comes along
  (``FrameMotion.boundary_flow``): each view's segment boundaries are moved to where it
  puts them (:func:`relabelled`, ``relabel_radius``), and near motion boundaries the
  boundary handling takes the blur from it (:func:`boundary_motion`).
- ``motion_source='gt'``: planes and motions fitted per superpixel (cut where the gt
  jumps) to the scene's gt/disparity (frame i and its neighbour) and gt/flow; 2D
  displacements taken directly from gt/flow (:func:`gt_needs` lists the files).
- ``motion_source='initial-flow'``: the dense optical flow of the view alone
  (monocular); only ``kernels='displacement'`` can use it.
"""

from ..settings import (
    BOUNDARY_MASKS,
    BOUNDARY_WEIGHTS,
    KERNELS,
    MOTION_SOURCES,
    PAPER_ALPHA,
    DeblurSettings,
)
from .deconvolve import solve
from .exposure import ExposureEstimate, estimate_exposure, exposure_doubt
from .frame import build_view_operator, deblur_frame, deblur_stereo_frame, deblur_view
from .motion import (
    FrameMotion,
    StereoMotion,
    dense_flow,
    frame_motion,
    invert_flow,
    invert_known_flow,
    relabelled,
    sceneflow_motion,
    stereo_motion,
    to_right_view,
    view_dense_flow,
)
from .operator import (
    GateTrusts,
    ViewOperator,
    boundary_motion,
    build_operator,
    view_operator,
    visibility,
)
from .results import FrameResult, StereoFrameResult
from .weights import DataTerms, data_terms, frame_trust, gate_trusts, resolve_alpha
from .window import (
    FrameWindow,
    check_gt,
    gt_needs,
    neighbour_of,
    other_side,
    read_window,
    uses_boundary_flow,
)

__all__ = [
    "BOUNDARY_MASKS",
    "BOUNDARY_WEIGHTS",
    "KERNELS",
    "MOTION_SOURCES",
    "PAPER_ALPHA",
    "DataTerms",
    "DeblurSettings",
    "ExposureEstimate",
    "FrameMotion",
    "FrameResult",
    "FrameWindow",
    "GateTrusts",
    "StereoFrameResult",
    "StereoMotion",
    "ViewOperator",
    "boundary_motion",
    "build_operator",
    "build_view_operator",
    "check_gt",
    "data_terms",
    "deblur_frame",
    "deblur_stereo_frame",
    "deblur_view",
    "dense_flow",
    "estimate_exposure",
    "exposure_doubt",
    "frame_motion",
    "frame_trust",
    "gate_trusts",
    "gt_needs",
    "invert_flow",
    "invert_known_flow",
    "relabelled",
    "neighbour_of",
    "other_side",
    "read_window",
    "resolve_alpha",
    "sceneflow_motion",
    "solve",
    "stereo_motion",
    "to_right_view",
    "uses_boundary_flow",
    "view_dense_flow",
    "view_operator",
    "visibility",
]
