"""Camera model: projection, its inverse, rig.toml round trip and errors."""
import numpy as np
import pytest

from horsemocap.camera import Camera, Rig, RigError, read_rig, rotation_matrix, rotation_vector, write_rig

KC = [-0.1275, 0.0181, -0.00097, 0.00176, 0.0]  # thesis Table 8.1, left camera


def _cam(**kw):
    return Camera("left", (640, 480), [[729.8, 0, 326.6], [0, 728.2, 234.6], [0, 0, 1]], KC, **kw)


def test_projection_matches_opencv():
    import cv2

    cam = _cam(rotation=[0.01, -0.02, 0.03], translation=[0.1, 0.0, 0.2])
    X = np.random.default_rng(0).uniform([-2, -1, 6], [2, 1, 9], (50, 3))
    ref, _ = cv2.projectPoints(X, cam.rotation, cam.translation, cam.matrix, cam.distortions)
    np.testing.assert_allclose(cam.project(X), ref.reshape(-1, 2), atol=1e-9)


def test_undistortion_inverts_distortion_over_the_image():
    cam = _cam()
    u, v = np.meshgrid(np.linspace(0, 639, 17), np.linspace(0, 479, 13))
    px = np.stack([u.ravel(), v.ravel()], -1)
    xn = cam.pixels_to_normalized(px)
    back = cam.normalized_to_pixels(xn)
    np.testing.assert_allclose(back, px, atol=1e-8)
    assert np.all(np.isnan(cam.pixels_to_normalized(np.array([[np.nan, 3.0]]))))


def test_rays_pass_through_the_point():
    cam = _cam(rotation=[0.0, 0.2, 0.0], translation=[-0.4, 0.0, 0.0])
    X = np.array([0.5, -0.3, 7.5])
    o, d = cam.rays(cam.project(X))
    np.testing.assert_allclose(np.cross(X - o, d), 0, atol=1e-9)


def test_rotation_vector_roundtrip():
    r = np.array([0.3, -0.2, 0.1])
    np.testing.assert_allclose(rotation_vector(rotation_matrix(r)), r, atol=1e-12)


def test_rig_toml_roundtrip(tmp_path):
    rig = Rig((_cam(), Camera("right", (640, 480), np.eye(3) * [700, 700, 1] + [[0, 0, 320], [0, 0, 240], [0, 0, 0]],
                             [0.1, 0, 0, 0, 0], [0.01, 0.02, 0.03], [-0.45, 0.0, 0.01])), {"adjusted": False, "error": 0.21})
    path = write_rig(rig, tmp_path / "rig.toml")
    back = read_rig(path)
    assert back.names == ["left", "right"] and back.metadata == {"adjusted": False, "error": 0.21}
    for a, b in zip(rig, back):
        np.testing.assert_array_equal(a.matrix, b.matrix)
        np.testing.assert_array_equal(a.translation, b.translation)


@pytest.mark.parametrize("text, pattern", [
    ("[cam_0]\nname = 'left'\n", r"\[cam_0\] has no field 'size'"),
    ("[cam_0]\nname='l'\nsize=[640,480]\nmatrix=[[1,0],[0,1]]\ndistortions=[0,0,0,0,0]\nrotation=[0,0,0]\ntranslation=[0,0,0]\n",
     r"field 'matrix' must have shape \(3, 3\)"),
    ("[metadata]\nerror = 1\n", r"no camera tables"),
    ("this is = not toml [", r"not valid TOML"),
])
def test_bad_rig_files_name_the_field(tmp_path, text, pattern):
    p = tmp_path / "rig.toml"
    p.write_text(text)
    with pytest.raises(RigError, match=pattern):
        read_rig(p)


def test_axis_rotations_match_rotation_matrix():
    from horsemocap.camera import axis_rotations, rotation_matrix

    angles = np.array([[0.3, -1.2], [2.0, 0.0]])
    for i, axis in enumerate("xyz"):
        R = axis_rotations(axis, angles)
        assert R.shape == (2, 2, 3, 3)
        for a, Ra in zip(angles.ravel(), R.reshape(-1, 3, 3)):
            np.testing.assert_allclose(Ra, rotation_matrix(np.eye(3)[i] * a), atol=1e-15)
    np.testing.assert_allclose(axis_rotations("z", np.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    with pytest.raises(ValueError, match="axis"):
        axis_rotations("w", 0.1)
