"""render(): the CLI's pixels to the bit, the pose in every form, the exact
derivatives against central differences taken from Python, no copies, and
the GIL released while rendering."""

import numpy as np
import pytest

import xgauge
from conftest import CUBOID, MACHINE, MATERIAL, ROTATION_DEG, TRANSLATION_MM, run_beside_python

SIZES = {"size_x": 20.0, "size_y": 30.0, "size_z": 10.0}


def test_equals_xgauge_render_to_the_bit(scene, cli):
    out = scene["folder"] / "cli.tif"
    cli("render", CUBOID, "--machine", scene["machine"], "--material", scene["material"],
        "--rotation-deg", *ROTATION_DEG, "--translation-mm", *TRANSLATION_MM,
        "--set", "size_x=20", "--set", "size_y=30", "--set", "size_z=10", "-n", "3",
        "--format", "f32", "-o", out, "-q")
    # Files and dicts alike.
    for machine, material in ((scene["machine"], scene["material"]), (MACHINE, MATERIAL)):
        rendered = xgauge.render(CUBOID, SIZES, (ROTATION_DEG, TRANSLATION_MM), machine,
                                 material, samples=3)
        assert rendered.image.shape == (128, 128) and rendered.image.dtype == np.float32
        assert np.array_equal(rendered.image, xgauge.read_tiff(out))


def test_pose_as_matrix_pair_or_dict_gives_the_same_image():
    pair = xgauge.render(CUBOID, None, (ROTATION_DEG, TRANSLATION_MM), MACHINE, MATERIAL)
    as_dict = xgauge.render(CUBOID, None, {"rotation_deg": ROTATION_DEG,
                                           "translation_mm": TRANSLATION_MM}, MACHINE, MATERIAL)
    assert np.array_equal(pair.image, as_dict.image)
    # A translation alone: the matrix is exact, so the image is too.
    matrix = np.eye(4)
    matrix[:3, 3] = TRANSLATION_MM
    by_matrix = xgauge.render(CUBOID, None, matrix, MACHINE, MATERIAL)
    by_pair = xgauge.render(CUBOID, None, ((0, 0, 0), TRANSLATION_MM), MACHINE, MATERIAL)
    assert np.array_equal(by_matrix.image, by_pair.image)
    # Path length without a material: the cuboid seen face on is size_z thick.
    path = xgauge.render(CUBOID, {"size_z": 12.5}, ((0, 0, 0), (0, 0, 400)), MACHINE, None)
    assert path.image[64, 64] == pytest.approx(12.5 * np.sqrt(1 + (0.25 / 1000) ** 2 * 2),
                                               rel=1e-6)


def test_bad_inputs_raise_xgauge_error():
    with pytest.raises(xgauge.Error, match="unknown dimension"):
        xgauge.render(CUBOID, {"size_w": 1.0}, ((0, 0, 0), (0, 0, 400)), MACHINE, MATERIAL)
    with pytest.raises(xgauge.Error, match="pose"):
        xgauge.render(CUBOID, None, [1, 2, 3], MACHINE, MATERIAL)
    with pytest.raises(xgauge.Error, match="widht"):
        bad = {"source_detector_distance_mm": 1000,
               "detector": {"columns": 128, "rows": 128, "pixel_pitch_mm": [0.5, 0.5],
                            "widht": 3}}
        xgauge.render(CUBOID, None, ((0, 0, 0), (0, 0, 400)), bad, MATERIAL)
    # A required key misspelled: the unknown key is named, not the missing one.
    with pytest.raises(xgauge.Error, match="unknown key 'detektor'; did you mean 'detector'"):
        bad = {"source_detector_distance_mm": 1000,
               "detektor": {"columns": 128, "rows": 128, "pixel_pitch_mm": [0.5, 0.5]}}
        xgauge.render(CUBOID, None, ((0, 0, 0), (0, 0, 400)), bad, MATERIAL)


def test_derivatives_are_views_in_model_order():
    r = xgauge.render(CUBOID, SIZES, (ROTATION_DEG, TRANSLATION_MM), MACHINE, MATERIAL,
                      derivatives=True)
    assert list(r.d_dimensions) == ["size_x", "size_y", "size_z"]
    assert list(r.d_pose) == ["rx", "ry", "rz", "x", "y", "z"]
    for d in [r.image, *r.d_dimensions.values(), *r.d_pose.values()]:
        assert d.shape == (128, 128) and d.dtype == np.float32
        assert not d.flags.owndata and type(d.base).__name__ == "PyCapsule"
    assert r.jacobian(["size_x", "z"]).shape == (128 * 128, 2)


# Central differences from Python against the analytic derivatives. The
# tolerance: on the pixels where the differences with steps h and h/2 agree
# to 1e-6 of the column's largest value (no sample's ray crossed an edge or
# a silhouette within the step: there the image has a kink and no difference
# tells its derivative; the gradient checker's rule, xray/derivatives.h),
# the derivative agrees with the difference to 1e-4 of that largest value.
STEP = 3e-4
TOLERANCE = 1e-4


def test_derivatives_match_central_differences():
    samples, region = 2, None  # the whole detector: every edge of the part is in view
    pose = (ROTATION_DEG, TRANSLATION_MM)
    analytic = xgauge.render(CUBOID, SIZES, pose, MACHINE, MATERIAL, samples=samples,
                             region=region, derivatives=True)
    names = list(SIZES) + ["rx", "ry", "rz", "x", "y", "z"]
    theta = list(SIZES.values()) + list(ROTATION_DEG) + list(TRANSLATION_MM)

    def image(t):
        return xgauge.render(CUBOID, t[:3], (t[3:6], t[6:9]), MACHINE, MATERIAL,
                             samples=samples, region=region, float64=True).image

    def difference(k, h):
        plus, minus = list(theta), list(theta)
        plus[k] += h
        minus[k] -= h
        return (image(plus) - image(minus)) / (2 * h)

    checked = 0
    for k, name in enumerate(names):
        d = analytic.d_dimensions.get(name, analytic.d_pose.get(name)).astype(np.float64)
        fd, fd_half = difference(k, STEP), difference(k, STEP / 2)
        scale = np.abs(fd).max()
        if scale < 1e-6:  # moves nothing in this view
            continue
        good = np.abs(fd - fd_half) <= 1e-6 * scale
        assert good.sum() >= 0.5 * good.size, name
        worst = np.abs(d - fd)[good].max() / scale
        assert worst <= TOLERANCE, f"{name}: {worst:.3g}"
        # The comparison covers pixels the parameter moves, not only zeros.
        assert (good & (np.abs(fd) > 0.1 * scale)).sum() >= 10, name
        checked += 1
    assert checked == len(names)


def test_a_4096_render_is_not_copied_and_releases_the_gil():
    """A 4096^2 render reaches numpy as the library's buffer, and a pure
    Python thread runs while it renders (it could not if the GIL were held)."""
    big = {"source_detector_distance_mm": 1000,
           "detector": {"columns": 4096, "rows": 4096, "pixel_pitch_mm": [0.05, 0.05]}}
    rendered, seconds, counted = run_beside_python(
        # 8 x 8 samples a pixel keep the render near half a second on two
        # cores (2 x 2 took under 0.1 s, too short to tell on a fast machine).
        lambda: xgauge.render(CUBOID, None, ((0, 0, 30), (0, 0, 400)), big, MATERIAL,
                              samples=8))
    image = rendered.image
    assert image.shape == (4096, 4096) and image.dtype == np.float32
    assert not image.flags.owndata and type(image.base).__name__ == "PyCapsule"
    assert image.min() < 0.7 and image.max() == 1.0  # the part's shadow, the open beam
    assert seconds > 0.1, "the render is too quick to tell"
    assert counted > 10, f"{counted} counts in {seconds:.2f} s"
