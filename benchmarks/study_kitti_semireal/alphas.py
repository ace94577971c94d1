import sys, numpy as np
from dataclasses import replace
from stereodeblur.evaluation.metrics import psnr, border_for
from stereodeblur.evaluation.paper_columns import COLUMNS
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import deblur_frame
from stereodeblur.settings import DeblurSettings
name = sys.argv[1]
scene = open_scene(f'/tmp/kitti/semireal/{name}')
sharp = scene.read_gt_sharp('left', 1); b = border_for(scene.shape[1])
for key in sys.argv[2].split(','):
    col = next(c for c in COLUMNS if c.key == key)
    s = col.settings(DeblurSettings())
    extra = sys.argv[3] if len(sys.argv) > 3 else ''
    if extra:
        s = replace(s, alpha=float(extra))
    r = deblur_frame(scene, 1, view='left', settings=s)
    obs = [(o.name if hasattr(o,'name') else str(o))[:40] for o in r.observations] if r.observations else []
    print(name, key, extra, 'alpha', r.alpha, 'psnr', round(psnr(r.image, sharp, border=b),2), 'obs', len(r.observations), flush=True)
