"""Point clouds of frames, PLY files, and rendering them from other viewpoints."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stereodeblur.errors import InputError
from stereodeblur.geometry.camera import StereoCamera
from stereodeblur.io.formats import linear_to_srgb
from stereodeblur.pointcloud import (
    PointCloud,
    frame_point_cloud,
    read_ply,
    render_view,
    write_ply,
)
from stereodeblur.sceneflow.model import SceneFlow

H, W = 24, 33
DEPTH = 2.0
K = np.array([[30.0, 0.0, 16.0], [0.0, 30.0, 11.0], [0.0, 0.0, 1.0]])  # centre on a pixel


def _plane(view="left"):
    camera = StereoCamera(K, 0.1)
    return SceneFlow(
        camera,
        np.zeros((H, W), np.int32),
        np.array([[0.0, 0.0, 1.0 / DEPTH]]),
        np.zeros((1, 6)),
        np.zeros((H, W), bool),
        view=view,
    )


def _image(seed=0):
    return np.random.default_rng(seed).random((H, W, 3)).astype(np.float32)


def _u8(image):
    return np.rint(image * 255) / 255


def test_ply_round_trip(tmp_path):
    cloud = frame_point_cloud(_plane(), _image(0), blurred=_image(1))
    path = write_ply(tmp_path / "c.ply", cloud, comments=["frame 3 view left"])
    assert path.read_bytes().startswith(b"ply\nformat binary_little_endian 1.0\n")
    back = read_ply(path)
    np.testing.assert_array_equal(back.points, cloud.points)
    np.testing.assert_array_equal(back.colors, cloud.colors)
    np.testing.assert_array_equal(back.blurred_colors, cloud.blurred_colors)
    np.testing.assert_array_equal(back.K, K)
    assert back.size == (W, H) and len(back) == H * W


def test_ascii_ply_from_elsewhere(tmp_path):
    (tmp_path / "a.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
        "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
        "element face 0\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 1 255 0 0\n0.5 0 2 0 255 0\n"
    )
    cloud = read_ply(tmp_path / "a.ply")
    np.testing.assert_array_equal(cloud.points, [[0, 0, 1], [0.5, 0, 2]])
    np.testing.assert_array_equal(cloud.colors, [[255, 0, 0], [0, 255, 0]])
    assert cloud.blurred_colors is None and cloud.K is None


@pytest.mark.parametrize(
    "data, fragment",
    [
        (b"not a ply", "not a PLY"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\n"
         b"property float y\nproperty float z\nend_header\n" + bytes(12), "truncated"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
         b"end_header\n" + bytes(4), "no 'y'"),
    ],
)  # fmt: skip
def test_malformed_ply(tmp_path, data, fragment):
    (tmp_path / "bad.ply").write_bytes(data)
    with pytest.raises(InputError, match=fragment):
        read_ply(tmp_path / "bad.ply")


def test_the_cloud_seen_from_its_own_camera_is_the_frame():
    image = _image(2)
    for view in ("left", "right"):
        cloud = frame_point_cloud(_plane(view), image)
        centre = _plane(view).camera.center(view)
        rendered = render_view(cloud, translation=centre)
        assert rendered.mask.all()
        np.testing.assert_allclose(rendered.image, _u8(image), atol=1e-6)
        np.testing.assert_allclose(rendered.depth, DEPTH, rtol=1e-6)


def test_a_sideways_step_shifts_a_fronto_parallel_plane():
    image = _image(3)
    cloud = frame_point_cloud(_plane(), image)
    step = 3 * DEPTH / K[0, 0]  # three pixels of disparity
    rendered = render_view(cloud, translation=(step, 0.0, 0.0))
    np.testing.assert_allclose(rendered.image[:, : W - 3], _u8(image)[:, 3:], atol=1e-6)
    assert rendered.mask[:, : W - 3].all() and not rendered.mask[:, W - 3 :].any()


def test_half_the_distance_doubles_the_size_and_fills_the_gaps():
    image = _image(4)
    cloud = frame_point_cloud(_plane(), image)
    rendered = render_view(cloud, translation=(0.0, 0.0, DEPTH / 2))
    cx, cy = int(K[0, 2]), int(K[1, 2])
    xs = np.arange(cx - 14, cx + 15, 2)  # even offsets from the principal point
    ys = np.arange(cy - 10, cy + 11, 2)
    for y in ys:
        for x in xs:
            source = image[cy + (y - cy) // 2, cx + (x - cx) // 2]
            np.testing.assert_allclose(rendered.image[y, x], _u8(source), atol=1e-6)
    assert rendered.mask[1:-1, 1:-1].all()  # gaps between the points are filled


def test_colours_sets_and_encoding():
    image, blurred = _image(5), _image(6)
    cloud = frame_point_cloud(_plane(), image, blurred=blurred, color="srgb")
    np.testing.assert_array_equal(
        cloud.colors, np.rint(linear_to_srgb(image) * 255).reshape(-1, 3).astype(np.uint8)
    )
    both = render_view(cloud, colors="both").image
    assert both.shape == (H, 2 * W, 3)
    np.testing.assert_allclose(both[:, W:], render_view(cloud, colors="blurred").image)
    with pytest.raises(InputError, match="blurred"):
        render_view(PointCloud(cloud.points, cloud.colors, K=K, size=(W, H)), colors="both")
    with pytest.raises(InputError, match="intrinsics"):
        render_view(PointCloud(cloud.points, cloud.colors))


@pytest.mark.parametrize(
    "comment, fragment",
    [
        ("comment K 1 0 0 0 1 0 0 0 x", "could not convert"),
        ("comment K nan 0 0 0 1 0 0 0 1", "finite"),
        ("comment K -5 0 0 0 5 0 0 0 1", "focal lengths > 0"),
        ("comment size 100000 100000", "at most"),
        ("comment size ten 3", "invalid literal"),
    ],
)
def test_bad_camera_comments_name_the_file(tmp_path, comment, fragment):
    path = tmp_path / "bad.ply"
    header = "ply\nformat ascii 1.0\n" + comment + "\nelement vertex 1\n"
    header += "property float x\nproperty float y\nproperty float z\nend_header\n"
    path.write_text(header + "0 0 1\n")
    with pytest.raises(InputError, match=fragment) as info:
        read_ply(path)
    assert "bad.ply" in str(info.value)


# --- fuzzing the PLY reader: a PointCloud or an InputError, never anything else

FUZZ = settings(
    max_examples=200,
    deadline=None,
    derandomize=True,  # the same examples on every run
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
TYPES = ["float", "double", "uchar", "int", "char", "short", "list uchar int", "bogus"]


def _read(path, data: bytes):
    path.write_bytes(data)
    try:
        cloud = read_ply(path)
    except InputError:
        return None
    assert isinstance(cloud, PointCloud)
    return cloud


@FUZZ
@given(data=st.binary(max_size=400))
def test_arbitrary_bytes(tmp_path, data):
    _read(tmp_path / "a.ply", data)
    _read(tmp_path / "b.ply", b"ply\n" + data)


@st.composite
def ply_files(draw):
    fmt = draw(st.sampled_from(["ascii", "binary_little_endian", "binary_big_endian", "x"]))
    count = draw(st.sampled_from(["0", "1", "3", "-1", "99999999999999", "x"]))
    prop = st.tuples(st.sampled_from(TYPES), st.sampled_from(["x", "y", "z", "red", "q"]))
    # Mostly x, y and z in some order (so the reader gets past its first checks), plus extras.
    xyz = [(draw(st.sampled_from(TYPES[:3])), axis) for axis in draw(st.permutations("xyz"))]
    if draw(st.booleans()):
        props = xyz + draw(st.lists(prop, max_size=2))
    else:
        props = draw(st.lists(prop, max_size=6))
    comments = draw(
        st.lists(
            st.sampled_from(
                [
                    "comment K 50 0 20 0 50 16 0 0 1",
                    "comment K 0 0 0 0 0 0 0 0 0",
                    "comment K 1e400 0 0 0 1 0 0 0 1",
                    "comment size 40 32",
                    "comment size -4 99999999999",
                    "comment size 1e3 2",
                ]
            ),
            max_size=3,
        )
    )
    lines = ["ply", f"format {fmt} 1.0", *comments, f"element vertex {count}"]
    lines += [f"property {kind} {name}" for kind, name in props]
    header = ("\n".join(lines) + "\nend_header\n").encode()
    body = draw(
        st.one_of(
            st.binary(max_size=64),
            st.lists(
                st.sampled_from(["0 0 1", "1 2 3 4 5 6", "nan 0 1", "1e999 0 0", "a b c", ""]),
                max_size=4,
            ).map(lambda rows: "\n".join(rows).encode()),
        )
    )
    return header + body


@FUZZ
@given(data=ply_files())
def test_ply_shaped_files(tmp_path, data):
    _read(tmp_path / "c.ply", data)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_a_property_declared_twice(tmp_path, fmt):
    header = f"ply\nformat {fmt} 1.0\nelement vertex 1\nproperty float x\nproperty float x\n"
    header += "property float y\nproperty float z\nend_header\n"
    body = b"0 1 2 3\n" if fmt == "ascii" else bytes(16)
    with pytest.raises(InputError, match="declared twice"):
        read_ply(_write(tmp_path / "dup.ply", header.encode() + body))


def _write(path, data: bytes):
    path.write_bytes(data)
    return path


def test_the_fuzzer_reaches_valid_clouds(tmp_path):
    header = "ply\nformat ascii 1.0\ncomment size 40 32\nelement vertex 1\n"
    header += "property float x\nproperty float y\nproperty float z\nend_header\n"
    cloud = _read(tmp_path / "ok.ply", (header + "0 0 1\n").encode())
    assert cloud is not None and cloud.size == (40, 32) and len(cloud) == 1
    with pytest.raises(InputError):
        read_ply(tmp_path / "ok.ply").__class__(cloud.points, cloud.colors, size=(0, 1))
