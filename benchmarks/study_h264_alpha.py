"""Study: does a larger prior weight recover the gain H.264 takes away? (Not a default.)

    python benchmarks/study_h264_alpha.py --scenes SCENES_DIR --work DIR \\
        family_0000,street_0000,family_0001,street_0001,family_0002,street_0002

Training scenes of the calibration protocol (``calibrate_defaults.py``'s ``--work``/scenes),
through ``camera_output.py``'s camera and H.264; frame 1, left view, defaults with the
held-out alpha and with alpha fixed at 1e-3, 3e-3 and 1e-2; PSNR dB in 8-bit sRGB.
"""

import argparse
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import camera_output as co

from stereodeblur.evaluation.metrics import border_for, psnr
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import deblur_frame
from stereodeblur.settings import DeblurSettings


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("names")
    parser.add_argument("--scenes", type=Path, required=True)
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--variants", default="h264,camera")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    alphas = ("held-out", 1e-3, 3e-3, 1e-2)
    for name in args.names.split(","):
        root = args.scenes / name
        truth = co.encode8(open_scene(root).read_gt_sharp("left", 1)) / 255.0
        border = border_for(truth.shape[1])
        for variant in args.variants.split(","):
            scene = open_scene(co.camera_scene(root, args.work, variant == "h264"))
            blurred = scene.read_frame("left", 1, linear=False)
            cells = []
            for alpha in alphas:
                settings = replace(DeblurSettings(), alpha=alpha)
                result = deblur_frame(scene, 1, view="left", settings=settings)
                score = psnr(co.encode8(result.image) / 255.0, truth, border=border)
                cells.append(f"{alpha}: {score:.2f} (alpha {result.alpha:.0e})")
            line = f"{name} {variant} input {psnr(blurred, truth, border=border):.2f} | "
            print(line + " | ".join(cells), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
