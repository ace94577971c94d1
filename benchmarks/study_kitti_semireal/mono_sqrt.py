import sys, json
import numpy as np
sys.path.insert(0, 'benchmarks')
import kitti_semireal as ks
from pathlib import Path
import stereodeblur.pipeline.motion as pm
from stereodeblur.sceneflow import initial
from stereodeblur.sceneflow.initial import to_gray, to_gray_u8
def enc(a):
    return to_gray_u8(np.sqrt(np.clip(to_gray(np.asarray(a, np.float32)), 0, 1)))
def view_dense_flow(window, view):
    blurred = window.blurred(view)
    fwd = initial.initial_optical_flow(enc(blurred), enc(window.frame(view, window.neighbour)))
    back = None
    if window.other is not None:
        back = initial.initial_optical_flow(enc(blurred), enc(window.frame(view, window.other)))
    return fwd, back
pm.view_dense_flow = view_dense_flow
method = sys.argv[1]
for name in ['000002','000002_noisy','000003','000003_noisy','000007','000007_noisy']:
    r = ks.deblur(Path('/tmp/kitti/semireal')/name, method, Path(f'/tmp/sqrtdense_{method}_{name}.json'))
    old = json.load(open(f'/tmp/kitti/semireal/{name}.{method}.json'))['psnr']
    print(name, method, round(old,2), '->', round(r['psnr'],2), flush=True)
