"""`stereodeblur deblur` over a whole clip: every frame of both views, options, reruns, logs."""

import json
import os
import shutil
import signal

import numpy as np

from stereodeblur.clip import deblur_clip
from stereodeblur.evaluation.metrics import psnr
from stereodeblur.io.formats import read_png
from stereodeblur.io.scene import open_scene
from stereodeblur.io.sources import SourceSpec
from stereodeblur.pipeline import DeblurSettings
from stereodeblur.pointcloud import read_ply
from tests.clip.clip_helpers import FAST, NUM_FRAMES, frame_files, run_cli


def _log(root):
    return [json.loads(line) for line in (root / "run-log.jsonl").read_text().splitlines()]


def test_every_frame_of_both_views_is_better_than_its_input(clip_scene, reference_run):
    assert reference_run.code == 0, reference_run.stderr
    out = reference_run.output
    assert frame_files(out) == [
        f"{v}/{i:06d}.png" for v in ("left", "right") for i in range(NUM_FRAMES)
    ]
    blurred, deblurred = open_scene(clip_scene), open_scene(out)
    assert (out / "camera.json").read_text() == (clip_scene / "camera.json").read_text()
    for view in ("left", "right"):
        for i in range(NUM_FRAMES):
            sharp = blurred.read_gt_sharp(view, i)
            before = psnr(blurred.read_frame(view, i), sharp)
            after = psnr(deblurred.read_frame(view, i), sharp)
            assert after > before + 1.0, (view, i, before, after)
    # The right view is deblurred for itself, not copied from the left.
    assert not np.allclose(deblurred.read_frame("left", 3), deblurred.read_frame("right", 3))


def test_progress_and_run_log(reference_run):
    err = reference_run.stderr
    assert "24/24" in err  # the CLI shows the clip's progress (bar or lines)
    log = _log(reference_run.output)
    assert [r["event"] for r in log] == ["start"] + ["frame"] * 24 + ["end"]
    start, frames, end = log[0], log[1:-1], log[-1]
    assert start["settings"]["num_irls"] == 2 and start["skipped"] == 0
    assert sorted((r["index"], r["view"]) for r in frames) == [
        (i, v) for i in range(NUM_FRAMES) for v in ("left", "right")
    ]
    for record in frames:
        assert record["status"] == "done"
        assert {"deconvolution", "write"} <= set(record["timings"])
        assert record["seconds"] >= sum(record["timings"].values()) - 1e-2
        assert isinstance(record["warnings"], list)
    assert end["done"] == 24 and end["failed"] == 0 and end["frames_per_minute"] > 0


def test_rerun_skips_finished_frames_and_refuses_other_settings(
    clip_scene, reference_run, tmp_path
):
    out = tmp_path / "out"
    shutil.copytree(reference_run.output, out)
    before = {p: (out / p).read_bytes() for p in frame_files(out)}
    (out / "left" / "000005.png").unlink()
    result = run_cli("deblur", clip_scene, "-o", out, "--workers", "1", "-q", *FAST)
    assert result.code == 0, result.stderr
    assert "1 frame(s)" in result.stdout and "23 already done" in result.stdout
    assert {p: (out / p).read_bytes() for p in frame_files(out)} == before
    assert _log(out)[-1]["done"] == 1

    other = [a if a != "5" else "6" for a in FAST]  # --cg 6
    result = run_cli("deblur", clip_scene, "-o", out, "-q", *other)
    assert result.code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "settings" in lines[0] and "overwrite" in lines[0]


def test_frames_and_views_select_the_work(clip_scene, reference_run, tmp_path):
    out = tmp_path / "out"
    result = run_cli(
        "deblur", clip_scene, "-o", out, "--frames", "3:5", "--views", "right", "-q", *FAST,
        "--workers", "1",
    )  # fmt: skip
    assert result.code == 0, result.stderr
    assert frame_files(out) == ["right/000003.png", "right/000004.png"]
    for name in frame_files(out):
        assert (out / name).read_bytes() == (reference_run.output / name).read_bytes()


def test_two_local_workers_give_the_serial_result(clip_scene, reference_run, tmp_path):
    out = tmp_path / "out"
    result = run_cli(
        "deblur", clip_scene, "-o", out, "--frames", "9:12", "--workers", "2", "-q", *FAST
    )
    assert result.code == 0, result.stderr
    assert len(frame_files(out)) == 6
    for name in frame_files(out):
        assert (out / name).read_bytes() == (reference_run.output / name).read_bytes()
    workers = {r["worker"] for r in _log(out) if r["event"] == "frame"}
    assert len(workers) == 2


def test_point_clouds_carry_geometry_and_deblurred_colours(clip_scene, tmp_path):
    out = tmp_path / "out"
    result = run_cli(
        "deblur", clip_scene, "-o", out, "--frames", "4", "--point-cloud", "-q", "--workers", "1",
        *FAST,
    )  # fmt: skip
    assert result.code == 0, result.stderr
    scene = open_scene(clip_scene)
    camera = scene.info.camera
    for view in ("left", "right"):
        cloud = read_ply(out / "pointcloud" / view / "000004.ply")
        H, W = scene.shape
        assert len(cloud) == H * W and cloud.size == (W, H)
        np.testing.assert_allclose(cloud.K, camera.K)
        # Every point projects onto the centre of its own pixel of this view ...
        xy = camera.project(cloud.points.astype(np.float64), view)
        pixel = np.rint(xy).astype(int)
        np.testing.assert_allclose(xy, pixel, atol=1e-3)
        # ... at the true depth (planes fitted to the ground truth) ...
        disparity = camera.depth_to_disparity(cloud.points[:, 2].astype(np.float64))
        truth = scene.read_gt_disparity(view, 4)[pixel[:, 1], pixel[:, 0]]
        assert np.median(np.abs(disparity - truth)) < 0.05
        # ... with the colour of the deblurred frame and of the blurred one.
        frame = read_png(out / view / "000004.png")[pixel[:, 1], pixel[:, 0]]
        np.testing.assert_array_equal(cloud.colors, np.rint(frame * 255).astype(np.uint8))
        blurred = scene.read_frame(view, 4)[pixel[:, 1], pixel[:, 0]]
        np.testing.assert_array_equal(cloud.blurred_colors, np.rint(blurred * 255))

    picture = tmp_path / "view.png"
    result = run_cli(
        "render-view", out / "pointcloud" / "left" / "000004.ply", "-o", picture,
        "--colors", "both",
    )  # fmt: skip
    assert result.code == 0, result.stderr
    side_by_side = read_png(picture)
    assert side_by_side.shape == (48, 128, 3)
    np.testing.assert_allclose(
        side_by_side[:, :64], read_png(out / "left" / "000004.png"), atol=0.5 / 255 + 1e-6
    )
    np.testing.assert_allclose(
        side_by_side[:, 64:], scene.read_frame("left", 4), atol=0.5 / 255 + 1e-6
    )


def test_point_clouds_need_scene_flow_geometry(clip_scene, tmp_path):
    out = tmp_path / "out"
    result = run_cli(
        "deblur", clip_scene, "-o", out, "--point-cloud", "--motion-source", "initial-flow",
        "--kernels", "displacement",
    )  # fmt: skip
    assert result.code == 2
    assert "point clouds" in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_a_killed_local_worker_has_its_frames_run_again(clip_scene, reference_run, tmp_path):
    out = tmp_path / "out"
    killed = []

    def kill_a_busy_worker(record):
        if not killed and record.status == "done":
            pid = int(record.worker.rsplit(":", 1)[1])
            os.kill(pid, signal.SIGKILL)  # a worker process this run started
            killed.append(pid)

    report = deblur_clip(
        SourceSpec.from_arguments(clip_scene),
        out,
        frames=range(4),
        settings=DeblurSettings(motion_source="gt", num_irls=2, num_cg=5, num_samples=16),
        workers=2,
        progress=False,
        on_frame=kill_a_busy_worker,
    )
    assert killed and report.failed == () and report.done == 8
    assert len(frame_files(out)) == 8
    for name in frame_files(out):
        assert (out / name).read_bytes() == (reference_run.output / name).read_bytes()
    workers = [r.worker for r in report.records]
    # Only the frame it had finished is its own: its next frame went elsewhere.
    assert len({r.index for r in report.records if r.worker.endswith(f":{killed[0]}")}) == 1
    assert len(set(workers)) >= 2
