"""The columns of the paper's Tables 2, 3 and 4 and the results they give.

Frame 1 of the left view of every scene is deblurred by each *column*, a
combination of the pipeline's settings (:class:`~stereodeblur.pipeline.DeblurSettings`):

============================  ===============  ============  =================  ========
column                        motion source    kernels       boundary weights   alpha
============================  ===============  ============  =================  ========
ground-truth 2D displacement  gt               displacement  none               0.001
initial optical flow          initial-flow     displacement  none               0.001
2D projection of scene flow   sceneflow        displacement  none               0.001
3D homographies               sceneflow        homography    none               0.001
paper (full)                  sceneflow        homography    paper (Eq. 5)      0.001
monocular (same defaults)     initial-flow     displacement  adaptive           default
ours (full)                   sceneflow        homography    gated (default)    default
============================  ===============  ============  =================  ========

Every column but "ours (full)" (and the true-motion and sweep runs of it, which take the
default ``observations``) deblurs each frame from its single observation; the paper's five
columns sample the sharp image bilinearly, "monocular" and "ours" with the default
``interpolation``. The paper's five columns and Table 2 run the paper's 10 IRLS x 25 CG
iterations; "monocular" and "ours" the default counts (both set by ``--irls`` / ``--cg`` when
given).

"Monocular (same defaults)" is the strongest monocular alternative: our solver, alpha rule
(``'held-out'`` is ``'auto'`` there: no other view) and boundary handling on the initial
optical flow (the handling of
:data:`~stereodeblur.settings.MONOCULAR_BOUNDARY_WEIGHTS`). Table 2 ("without motion
discontinuities") repeats the first four with ``boundary_mask='gt'``: the scene's gt/mixed
pixels get weight 0 throughout. Tables 3 (PSNR) and 4 (SSIM) use all seven columns without
the mask. A seventh run,
"ours, true motion" (:data:`TRUE_MOTION`: ours full with motion source gt, the same
piecewise-planar model fitted to the true disparity and flow), is no method but shows how
far a better motion estimate could take the blur model. The alpha sweep deblurs with
"ours (full)" at every alpha of :data:`ALPHA_SWEEP` and compares with the default alpha.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from ..settings import (
    DEFAULT_ALPHA,
    DEFAULT_BOUNDARY_WEIGHTS,
    DEFAULT_INTERPOLATION,
    DEFAULT_OBSERVATIONS,
    DEFAULT_RANGE_GUARD,
    MONOCULAR_BOUNDARY_WEIGHTS,
    NUM_CG,
    NUM_IRLS,
    PAPER_ALPHA,
    PAPER_CG,
    PAPER_IRLS,
    DeblurSettings,
)

FRAME = 1
ALPHA_SWEEP = (3e-5, 1e-4, 3e-4, 1e-3, 3e-3)


@dataclass(frozen=True)
class Column:
    """One method of the tables: a combination of the pipeline's switches."""

    key: str
    title: str
    motion_source: str
    kernels: str
    boundary_weights: str = "none"
    alpha: float | str = PAPER_ALPHA
    boundary_mask: str | None = None
    observations: str = "single"
    paper_solver: bool = False
    interpolation: str = "bilinear"
    range_guard: bool = False

    def settings(self, base: DeblurSettings) -> DeblurSettings:
        """``base`` (a DeblurSettings) with this column's switches; a column of the paper's
        method (``paper_solver``) takes the paper's iteration counts where ``base`` has the
        default ones."""
        counts = (base.num_irls, base.num_cg)
        if self.paper_solver and counts == (NUM_IRLS, NUM_CG):
            counts = (PAPER_IRLS, PAPER_CG)
        return replace(
            base,
            num_irls=counts[0],
            num_cg=counts[1],
            motion_source=self.motion_source,
            kernels=self.kernels,
            boundary_weights=self.boundary_weights,
            alpha=self.alpha,
            boundary_mask=self.boundary_mask,
            observations=self.observations,
            interpolation=self.interpolation,
            range_guard=self.range_guard,
        )

    def describe(self) -> str:
        """The column's settings, e.g. ``motion_source=gt, kernels=displacement, ...``."""
        mask = f", boundary_mask={self.boundary_mask}" if self.boundary_mask else ""
        seen = f", observations={self.observations}" if self.observations != "single" else ""
        if self.interpolation != "bilinear":
            seen += f", interpolation={self.interpolation}"
        if self.range_guard:
            seen += ", range_guard"
        return (
            f"motion_source={self.motion_source}, kernels={self.kernels}, "
            f"boundary_weights={self.boundary_weights}, alpha={self.alpha}{mask}{seen}"
        )


COLUMNS = (
    Column("gt-displacement", "gt 2D displacement", "gt", "displacement", paper_solver=True),
    Column(
        "initial-flow", "initial optical flow", "initial-flow", "displacement", paper_solver=True
    ),
    Column(
        "sceneflow-2d",
        "2D projection of scene flow",
        "sceneflow",
        "displacement",
        paper_solver=True,
    ),
    Column("homographies", "3D homographies", "sceneflow", "homography", paper_solver=True),
    Column("paper-full", "paper (full)", "sceneflow", "homography", "paper", paper_solver=True),
    Column(
        "monocular",
        "monocular (same defaults)",
        "initial-flow",
        "displacement",
        MONOCULAR_BOUNDARY_WEIGHTS,
        DEFAULT_ALPHA,
        interpolation=DEFAULT_INTERPOLATION,
        range_guard=DEFAULT_RANGE_GUARD,
    ),
    Column(
        "ours-full",
        "ours (full)",
        "sceneflow",
        "homography",
        DEFAULT_BOUNDARY_WEIGHTS,
        DEFAULT_ALPHA,
        observations=DEFAULT_OBSERVATIONS,
        interpolation=DEFAULT_INTERPOLATION,
        range_guard=DEFAULT_RANGE_GUARD,
    ),
)
"""Tables 3 and 4."""

MASKED_COLUMNS = tuple(replace(c, key="masked-" + c.key, boundary_mask="gt") for c in COLUMNS[:4])
"""Table 2: the 2D and 3D kernels with gt/mixed masked out."""

FULL_KEYS = ("paper-full", "ours-full")

TRUE_MOTION = Column(
    "ours-true-motion",
    "ours, true motion",
    "gt",
    "homography",
    DEFAULT_BOUNDARY_WEIGHTS,
    DEFAULT_ALPHA,
    observations=DEFAULT_OBSERVATIONS,
    interpolation=DEFAULT_INTERPOLATION,
)
"""Ours (full) with the scene flow fitted to the true disparity and flow: how far a better
motion estimate could take the blur model (not a method; kept out of Tables 3 and 4)."""


def sweep_column(alpha: float) -> Column:
    """ "ours (full)" at a fixed ``alpha``."""
    return Column(
        f"sweep-{alpha:g}",
        f"ours, alpha {alpha:g}",
        "sceneflow",
        "homography",
        DEFAULT_BOUNDARY_WEIGHTS,
        alpha,
        observations=DEFAULT_OBSERVATIONS,
        range_guard=DEFAULT_RANGE_GUARD,
    )


@dataclass(frozen=True)
class ColumnResult:
    """One column on one scene.

    ``aep`` / ``ade`` are NaN where the column has no such estimate; the weight
    statistics are NaN for fixed weights. ``mixed_mse``: the mean squared error in the
    scene's gt/mixed pixels (whose exposure mixes surfaces).
    """

    column: str
    psnr: float
    ssim: float
    aep: float
    ade: float
    alpha: float
    seconds: float
    low_weight_percent: float = math.nan
    low_weight_explained_percent: float = math.nan
    changed_last_percent: float = math.nan
    signature: dict = field(default_factory=dict)
    mixed_mse: float = math.nan


@dataclass(frozen=True)
class SceneResult:
    """All columns on one scene, plus the blurred input's scores."""

    scene: str
    kind: str  # 'object' or 'planar'
    noisy: bool
    size: str
    psnr_blurred: float
    ssim_blurred: float
    columns: dict
    sceneflow_seconds: float = math.nan
    warnings: tuple[str, ...] = ()
    mixed_mse_blurred: float = math.nan
