import sys, time
from dataclasses import replace
from stereodeblur.evaluation.metrics import psnr, border_for
from stereodeblur.evaluation.paper_columns import COLUMNS
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import deblur_frame
from stereodeblur.settings import DeblurSettings
base = next(c for c in COLUMNS if c.key == 'ours-full').settings(DeblurSettings())
variants = {
  'segments x2': dict(num_segments=3600),
  'single': dict(observations='single'),
  'boundary adaptive': dict(boundary_weights='adaptive'),
  'boundary none': dict(boundary_weights='none'),
  'displacement kernels': dict(kernels='displacement'),
}
for name in sys.argv[1].split(','):
    scene = open_scene(f'/tmp/kitti/semireal/{name}')
    sharp = scene.read_gt_sharp('left', 1); b = border_for(scene.shape[1])
    for v in sys.argv[2].split(','):
        t = time.time()
        try:
            r = deblur_frame(scene, 1, view='left', settings=replace(base, **variants[v]))
            print(name, v, f"{psnr(r.image, sharp, border=b):.2f}", f"{time.time()-t:.0f}s", flush=True)
        except Exception as e:
            print(name, v, 'failed', type(e).__name__, str(e)[:200], flush=True)
