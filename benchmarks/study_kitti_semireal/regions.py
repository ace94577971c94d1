import sys, numpy as np
sys.path.insert(0, 'benchmarks')
from pathlib import Path
import kitti_semireal as ks
from stereodeblur.evaluation.metrics import border_for
from stereodeblur.evaluation.paper_columns import COLUMNS
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import deblur_frame
from stereodeblur.settings import DeblurSettings
name = sys.argv[1]
photo, _ = ks.photo_scene(Path('/tmp/kitti/training'), name[:6])
scene = open_scene(f'/tmp/kitti/semireal/{name}')
sharp = scene.read_gt_sharp('left', 1); b = border_for(scene.shape[1])
mixed = scene.read_gt_mixed('left', 1) if hasattr(scene, 'read_gt_mixed') else None
moving = photo.labels['left'] > 0
H, W = sharp.shape
inner = np.zeros((H, W), bool); inner[b:-b, b:-b] = True
res = {}
for key in ('ours-full', 'monocular'):
    col = next(c for c in COLUMNS if c.key == key)
    r = deblur_frame(scene, 1, view='left', settings=col.settings(DeblurSettings()))
    err = (r.image - sharp) ** 2
    res[key] = err
    np.save(f'/tmp/{name}_{key}.npy', r.image)
from scipy import ndimage
near_moving = ndimage.binary_dilation(moving, iterations=15)
regions = {'all': inner, 'moving objects (+15 px)': inner & near_moving, 'static': inner & ~near_moving}
if mixed is not None:
    regions['mixed'] = inner & mixed.astype(bool)
d = photo.disparity['left']
edges = ndimage.maximum_filter(d, 5) - ndimage.minimum_filter(d, 5) > 1.0
regions['depth edges (5 px)'] = inner & edges & ~near_moving
regions['smooth depth'] = inner & ~edges & ~near_moving
for k, m in regions.items():
    a, c = res['ours-full'][m].mean(), res['monocular'][m].mean()
    print(f"{name} {k:26s} share {m.mean()/inner.mean():.3f}  mse ours {a*1e4:.2f}  mono {c*1e4:.2f} (x1e-4)  dB ours-mono {10*np.log10(c/a):+.2f}")
