"""Study: does the fit to the frames tell a too-long exposure from the true one? (Not a default.)

    python benchmarks/study_exposure_fit.py --scenes SCENES_DIR --factors 0.6667,1,1.5 \\
        family_0000,street_0000,family_0002,street_0002,family_0005,street_0005,family_0007,street_0004

Training scenes of the calibration protocol (``calibrate_defaults.py``'s ``--work``/scenes).
Frame 1 of both views is deblurred with the defaults and the estimated motion, told the true
exposure times each factor (at most the frame interval); printed for the left view: its PSNR,
the root mean square of its own blurred frame's residual (the result re-blurred by the view's
operator at that exposure) and of the right view's predicted from it.
"""

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

from stereodeblur.evaluation.metrics import border_for, psnr
from stereodeblur.io.scene import open_scene
from stereodeblur.io.sources import open_source
from stereodeblur.pipeline import deblur_stereo_frame
from stereodeblur.pipeline.alpha import other_view, pixel_errors, prediction_error
from stereodeblur.pipeline.frame import build_view_operator
from stereodeblur.pipeline.window import read_window
from stereodeblur.settings import DeblurSettings


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("names")
    parser.add_argument("--scenes", type=Path, required=True)
    parser.add_argument("--factors", default="0.6667,1,1.5")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    settings = DeblurSettings()
    for name in args.names.split(","):
        root = args.scenes / name
        truth_scene = open_scene(root)
        truth = truth_scene.read_gt_sharp("left", 1)
        timing = truth_scene.info.exposure
        border = border_for(truth.shape[1])
        for factor in map(float, args.factors.split(",")):
            exposure = min(factor * timing.exposure, 1 / timing.frame_rate)
            scene = open_source(root, exposure=exposure)
            stereo = deblur_stereo_frame(scene, 1)
            left = stereo.frames["left"]
            window = read_window(scene, 1, ("left", "right"), settings)
            views = stereo.motion.views
            operators = {v: build_view_operator(window, views[v], settings) for v in views}
            image = np.clip(left.image, 0, 1)
            own = pixel_errors(
                operators["left"].operator.forward(image), left.blurred, border=border
            )
            right = other_view(operators["right"], views["right"], window.blurred("right"), "right")
            predicted = prediction_error(image, right, border=border)
            print(
                f"{name} x{factor:.2f} (duty {exposure * timing.frame_rate:.2f}) PSNR "
                f"{psnr(left.image, truth, border=border):.2f} (input "
                f"{psnr(left.blurred, truth, border=border):.2f}) own residual "
                f"{np.sqrt(own.mean()):.4f} right view {np.sqrt(predicted):.4f}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
