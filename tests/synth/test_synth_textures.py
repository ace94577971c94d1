import numpy as np
import pytest

from stereodeblur.errors import InputError
from stereodeblur.synth.textures import TEXTURE_NAMES, load_texture, srgb_to_linear


def test_at_least_six_textures_load_offline_as_linear_rgb():
    assert len(TEXTURE_NAMES) >= 6
    for name in TEXTURE_NAMES:
        texture = load_texture(name)
        assert texture.dtype == np.float32 and texture.ndim == 3 and texture.shape[2] == 3
        assert min(texture.shape[:2]) >= 400
        assert texture.min() >= 0 and texture.max() <= 1 and texture.std() > 0.02


def test_grey_texture_becomes_rgb_and_srgb_is_decoded():
    import skimage.data

    stored = skimage.data.camera().astype(np.float64) / 255
    encoded = load_texture("camera", decode_srgb=False)
    np.testing.assert_allclose(encoded[..., 0], stored, atol=1e-7)
    np.testing.assert_array_equal(encoded[..., 0], encoded[..., 2])
    linear = load_texture("camera")
    np.testing.assert_allclose(linear[..., 1], srgb_to_linear(stored), atol=1e-6)
    # The sRGB curve: 0.5 encodes about 0.214 of full irradiance.
    np.testing.assert_allclose(
        srgb_to_linear(np.array([0.0, 0.5, 1.0])), [0, 0.21404, 1], atol=1e-5
    )


def test_textures_are_fresh_copies():
    a = load_texture("brick")
    a[:] = 0
    assert load_texture("brick").max() > 0


def test_unknown_texture():
    with pytest.raises(InputError, match="unknown texture"):
        load_texture("nonexistent")
