"""The package ``__init__`` files lead to the paper's equations and load numba lazily."""

import subprocess
import sys

import stereodeblur.blur
import stereodeblur.deconv
from stereodeblur.blur.homography import homography_blur
from stereodeblur.deconv.irls import deblur_irls
from stereodeblur.deconv.weights import PaperWeights


def test_paper_equations_are_exported():
    assert stereodeblur.blur.homography_blur is homography_blur  # Eq. 3
    assert stereodeblur.deconv.PaperWeights is PaperWeights  # Eq. 5
    assert stereodeblur.deconv.deblur_irls is deblur_irls  # Eq. 6
    for package in (stereodeblur.blur, stereodeblur.deconv):
        assert set(package.__all__) <= set(dir(package))
        assert all(getattr(package, name) is not None for name in package.__all__)


def test_importing_the_packages_does_not_load_numba():
    code = "import sys, stereodeblur.blur, stereodeblur.deconv; print('numba' in sys.modules)"
    output = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert output.returncode == 0, output.stderr
    assert output.stdout.strip() == "False"
