import numpy as np

from stereodeblur.cli import main
from stereodeblur.evaluation.kernels_figure import kernel_grid, yaw_sceneflow
from stereodeblur.geometry import Exposure, se3_exp
from stereodeblur.io.formats import read_png

SIZE = (120, 90)


def test_kernels_differ_more_at_the_periphery_than_near_the_yaw_axis():
    kernels = kernel_grid(size=SIZE, yaw=0.3, grid=(5, 3))
    norms = kernels.difference_norm()
    assert norms.shape == (3, 5)
    centre = norms[:, 2]  # the column of pixels on the rotation axis
    periphery = norms[:, [0, 4]]
    assert periphery.min() > 3 * centre.max()
    # Both kernels are whole rows of blur matrices whose rows sum to one.
    np.testing.assert_allclose(kernels.homography.sum(axis=(2, 3)), 1.0, atol=1e-5)
    np.testing.assert_allclose(kernels.displacement.sum(axis=(2, 3)), 1.0, atol=1e-5)


def test_no_yaw_gives_identical_delta_kernels():
    kernels = kernel_grid(size=SIZE, yaw=0.0, grid=(3, 2))
    radius = kernels.homography.shape[2] // 2
    delta = np.zeros_like(kernels.homography[0, 0])
    delta[radius, radius] = 1.0
    np.testing.assert_allclose(kernels.homography, np.broadcast_to(delta, kernels.homography.shape))
    np.testing.assert_allclose(kernels.difference, 0.0, atol=1e-6)


def test_homography_kernel_centroid_follows_the_rotating_plane():
    """The centroid of a kernel is the mean reference position of what the pixel sees."""
    yaw, depth, num_samples = 0.3, 3.0, 70
    kernels = kernel_grid(size=SIZE, yaw=yaw, depth=depth, grid=(5, 3), num_samples=num_samples)
    sf = yaw_sceneflow(SIZE, yaw=yaw, depth=depth)
    camera, twist = sf.camera, sf.twists[0]
    x, y = kernels.pixels[0, 0]
    patch = kernels.homography[0, 0]
    radius = patch.shape[0] // 2
    dy, dx = np.mgrid[-radius : radius + 1, -radius : radius + 1]
    centroid = np.array([(patch * dx).sum() + x, (patch * dy).sum() + y])
    positions = []
    for s in Exposure(20.0, 0.04).sample_fractions(num_samples):
        M = se3_exp(s * twist)
        R, T = M[:3, :3], M[:3, 3]
        # Ray of pixel (x, y) against the plane z = depth moved to instant s.
        n = R @ np.array([0.0, 0.0, 1.0])
        point_on = R @ np.array([0.0, 0.0, depth]) + T
        d = camera.K_inv @ np.array([x, y, 1.0])
        Q = (n @ point_on) / (n @ d) * d
        P = R.T @ (Q - T)  # back to the reference pose
        q = camera.K @ P
        positions.append(q[:2] / q[2])
    np.testing.assert_allclose(centroid, np.mean(positions, axis=0), atol=1e-3)


def test_cli_writes_the_picture(tmp_path, capsys):
    out = tmp_path / "fig" / "kernels.png"
    assert main(["kernels", "-o", str(out), "--size", "120x90"]) == 0
    picture = read_png(out)
    assert picture.ndim == 3 and picture.shape[2] == 3
    assert picture.shape[1] > 2 * picture.shape[0]  # three panels side by side
    assert picture.std() > 0.05
    assert "L1 difference" in capsys.readouterr().out


def test_cli_rejects_a_bad_depth(tmp_path, capsys):
    assert main(["kernels", "-o", str(tmp_path / "k.png"), "--depth", "-1"]) == 2
    assert "depth" in capsys.readouterr().err


def test_cli_rejects_a_yaw_beyond_a_quarter_turn(tmp_path, capsys):
    assert main(["kernels", "-o", str(tmp_path / "k.png"), "--yaw", "1e9"]) == 2
    err = capsys.readouterr().err
    assert "--yaw" in err and "1.571" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "k.png").exists()
