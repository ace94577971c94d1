"""The benchmarks' stored motions are read back only for the estimator settings of their making."""

from dataclasses import replace

import numpy as np
import pytest

from stereodeblur.evaluation.motion_cache import (
    cached_motion,
    is_stored,
    motion_digest,
    motion_signature,
)
from stereodeblur.io.scene import open_scene
from stereodeblur.settings import DeblurSettings
from stereodeblur.synth.objects import make_object_scene
from stereodeblur.synth.planar import write_rendered_scene


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    root = tmp_path_factory.mktemp("motion_cache") / "squares"
    write_rendered_scene(make_object_scene("squares", size=(64, 48), num_samples=8), root)
    return open_scene(root)


def test_a_stored_scene_flow_is_reused_only_with_the_same_estimator(scene, tmp_path):
    settings = DeblurSettings()
    first, seconds, _ = cached_motion(scene, "sceneflow", settings, tmp_path)
    assert seconds > 0 and (tmp_path / "sceneflow.npz").is_file()
    again, seconds, _ = cached_motion(scene, "sceneflow", settings, tmp_path)
    assert seconds == 0.0
    np.testing.assert_array_equal(again.sceneflow.disparity(), first.sceneflow.disparity())

    other = replace(settings, sceneflow=replace(settings.sceneflow, census_threshold=0.004))
    assert motion_signature("sceneflow", other) != motion_signature("sceneflow", settings)
    _, seconds, _ = cached_motion(scene, "sceneflow", other, tmp_path)
    assert seconds > 0  # estimated again, not the stored one of the other band
    _, seconds, _ = cached_motion(scene, "sceneflow", other, tmp_path)
    assert seconds == 0.0
    _, seconds, _ = cached_motion(scene, "sceneflow", settings, tmp_path)
    assert seconds > 0


def test_a_motion_stored_without_a_signature_is_estimated_again(scene, tmp_path):
    for source in ("sceneflow", "initial-flow"):
        cached_motion(scene, source, DeblurSettings(), tmp_path)
        (tmp_path / f"{source}.signature").unlink()  # as stored before signatures
        _, seconds, _ = cached_motion(scene, source, DeblurSettings(), tmp_path)
        assert seconds > 0
        _, seconds, _ = cached_motion(scene, source, DeblurSettings(), tmp_path)
        assert seconds == 0.0


def test_is_stored_tells_a_motion_of_other_settings_from_a_current_one(scene, tmp_path):
    settings = DeblurSettings()
    other = replace(settings, sceneflow=replace(settings.sceneflow, census_threshold=0.004))
    assert not is_stored(tmp_path, "sceneflow", settings)
    cached_motion(scene, "sceneflow", settings, tmp_path)
    assert is_stored(tmp_path, "sceneflow", settings)
    assert not is_stored(tmp_path, "sceneflow", other)  # what the benchmark scripts refuse
    assert not is_stored(tmp_path, "gt", settings)  # never stored


def test_a_motion_stored_by_other_code_or_libraries_is_estimated_again(
    scene, tmp_path, monkeypatch
):
    from stereodeblur.evaluation import motion_cache

    settings = DeblurSettings()
    for source in ("sceneflow", "initial-flow"):
        cached_motion(scene, source, settings, tmp_path)
        assert is_stored(tmp_path, source, settings)
    monkeypatch.setattr(motion_cache, "estimator_fingerprint", lambda: "another")
    for source in ("sceneflow", "initial-flow"):
        assert not is_stored(tmp_path, source, settings)


def test_the_estimators_fingerprint_follows_its_libraries(monkeypatch):
    import numpy

    from stereodeblur.evaluation import motion_cache

    now = motion_cache.estimator_fingerprint()
    motion_cache.estimator_fingerprint.cache_clear()
    monkeypatch.setattr(numpy, "__version__", "0.0")
    try:
        assert motion_cache.estimator_fingerprint() != now
    finally:
        motion_cache.estimator_fingerprint.cache_clear()


def test_a_motion_digest_survives_storage_and_follows_the_motion(scene, tmp_path):
    for source in ("sceneflow", "initial-flow"):
        made, seconds, _ = cached_motion(scene, source, DeblurSettings(), tmp_path)
        read, again, _ = cached_motion(scene, source, DeblurSettings(), tmp_path)
        assert seconds > 0 and again == 0.0
        assert motion_digest(read) == motion_digest(made)
    sf = cached_motion(scene, "sceneflow", DeblurSettings(), tmp_path)[0]
    twists = sf.sceneflow.twists.copy()
    twists[0, 0] += 1e-9
    moved = replace(sf, sceneflow=replace(sf.sceneflow, twists=twists))
    assert motion_digest(moved) != motion_digest(sf)
    flows = replace(made, flow_forward=made.flow_forward + 1e-3)
    assert motion_digest(flows) != motion_digest(made)
