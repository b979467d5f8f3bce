"""Pinhole camera with lens distortion, camera rigs, and ``rig.toml``.

The camera model is the one of thesis section 3.4 (Bouguet's toolbox, which is
also OpenCV's): a point ``X_c`` in the camera frame is normalised,
``x_n = [X_c/Z_c, Y_c/Z_c]``, distorted with radial ``kc(1), kc(2), kc(5)``
(OpenCV ``k1, k2, k3``) and tangential ``kc(3), kc(4)`` (``p1, p2``) terms,
and mapped to pixels with the focal lengths ``fc`` and principal point ``cc``
(and optional skew ``alpha_c``).

A rig holds several cameras in one world frame, the frame of the reference
camera (thesis: the left camera, ``CM_L``). Extrinsics follow OpenCV:
``x_cam = R @ x_world + t``; for a pair this is the toolbox's
``x_right = R x_left + T`` (Table 8.4's ``R_ML, t_ML``).

``rig.toml`` is the aniposelib / anipose / caliscope camera format described in
``docs/sessions.md``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np

from .store import atomic_write_text, read_text_utf8

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib  # type: ignore


class RigError(ValueError):
    """A rig file or a rig description that breaks the contract.

    Examples
    --------
    >>> import numpy as np
    >>> try:
    ...     Camera("left", (640, 480), np.eye(3), distortions=np.zeros(6))
    ... except RigError as error:
    ...     print(error)
    camera 'left': distortions has 6 values, expected at most 5 [k1, k2, p1, p2, k3]
    """


@dataclass(frozen=True)
class Camera:
    """One calibrated camera.

    Parameters
    ----------
    name : str
        Camera name as used in the session (``"left"``...).
    size : tuple of int
        Image ``(width, height)`` in pixels.
    matrix : ndarray, shape (3, 3)
        Intrinsic matrix ``KK = [[fx, alpha*fx, cx], [0, fy, cy], [0, 0, 1]]``.
    distortions : ndarray, shape (5,)
        ``[k1, k2, p1, p2, k3]`` (Bouguet's ``kc``).
    rotation : ndarray, shape (3,)
        Rodrigues vector of ``R`` with ``x_cam = R x_world + t``.
    translation : ndarray, shape (3,)
        ``t`` in metres.

    Examples
    --------
    >>> import numpy as np
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> left = Camera("left", (640, 480), K)
    >>> left.project([0.1, 0.0, 2.0])                  # 10 cm right of the axis, 2 m away
    array([360., 240.])
    >>> left.pixels_to_normalized(np.array([360.0, 240.0]))
    array([0.05, 0.  ])
    >>> left.focal, left.principal_point
    (array([800., 800.]), array([320., 240.]))
    """

    name: str
    size: tuple[int, int]
    matrix: np.ndarray
    distortions: np.ndarray = field(default_factory=lambda: np.zeros(5))
    rotation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        object.__setattr__(self, "size", (int(self.size[0]), int(self.size[1])))
        object.__setattr__(self, "matrix", np.asarray(self.matrix, float).reshape(3, 3))
        dist = np.zeros(5)
        given = np.asarray(self.distortions, float).ravel()
        if given.size > 5:
            raise RigError(f"camera {self.name!r}: distortions has {given.size} values, expected at most 5 [k1, k2, p1, p2, k3]")
        dist[: given.size] = given
        object.__setattr__(self, "distortions", dist)
        object.__setattr__(self, "rotation", np.asarray(self.rotation, float).reshape(3))
        object.__setattr__(self, "translation", np.asarray(self.translation, float).reshape(3))

    # -- convenience views -------------------------------------------------
    @property
    def focal(self) -> np.ndarray:
        """``fc = [fx, fy]`` in pixels."""
        return np.array([self.matrix[0, 0], self.matrix[1, 1]])

    @property
    def principal_point(self) -> np.ndarray:
        """``cc = [cx, cy]`` in pixels."""
        return np.array([self.matrix[0, 2], self.matrix[1, 2]])

    @cached_property
    def rotation_matrix(self) -> np.ndarray:
        """``R`` (3, 3) from the Rodrigues vector (computed once per camera; read-only)."""
        R = rotation_matrix(self.rotation)
        R.setflags(write=False)
        return R

    @property
    def center(self) -> np.ndarray:
        """Optical centre in world coordinates, ``-R^T t``.

        Examples
        --------
        >>> Camera("right", (640, 480), np.eye(3), translation=[-0.5, 0.0, 0.0]).center
        array([0.5, 0. , 0. ])
        """
        return -self.rotation_matrix.T @ self.translation

    @property
    def projection_matrix(self) -> np.ndarray:
        """``P = K [R | t]`` (3, 4) for undistorted normalised pixels."""
        return self.matrix @ np.hstack([self.rotation_matrix, self.translation[:, None]])

    def with_pose(self, rotation, translation) -> "Camera":
        """A copy with other extrinsics."""
        return replace(self, rotation=np.asarray(rotation, float), translation=np.asarray(translation, float))

    # -- geometry ------------------------------------------------------------
    def world_to_camera(self, points_world: np.ndarray) -> np.ndarray:
        """Points ``(..., 3)`` from the world frame into this camera's frame."""
        p = np.asarray(points_world, float)
        return p @ self.rotation_matrix.T + self.translation

    def project(self, points_world: np.ndarray) -> np.ndarray:
        """Project world points ``(..., 3)`` to distorted pixels ``(..., 2)``.

        Thesis eq. 3.1-3.10 (pinhole, distortion, pixel mapping). Points at or
        behind the camera plane give NaN.

        Examples
        --------
        >>> import numpy as np
        >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
        >>> left = Camera("left", (640, 480), K)
        >>> left.project([[0.1, 0.0, 2.0], [0.0, 0.0, -1.0]])     # the second is behind the camera
        array([[360., 240.],
               [ nan,  nan]])
        """
        return self.camera_to_pixels(self.world_to_camera(points_world))

    def camera_to_pixels(self, points_camera: np.ndarray) -> np.ndarray:
        """Distorted pixels ``(..., 2)`` of points ``(..., 3)`` in this camera's frame (NaN at or behind
        the camera plane): :meth:`project` after :meth:`world_to_camera`.

        Examples
        --------
        A point given in the camera's own frame, 2 m in front of it and 0.1 m to the side, lands
        ``800 * 0.1 / 2 = 40`` px right of the principal point, wherever the camera stands in the world;
        :meth:`project` of the same point in world coordinates gives the same pixels:

        >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
        >>> right = Camera("right", (640, 480), K, translation=[-0.5, 0.0, 0.0])
        >>> right.camera_to_pixels([[0.1, 0.0, 2.0], [0.0, 0.0, 0.0]])     # the second is on the camera plane
        array([[360., 240.],
               [ nan,  nan]])
        >>> bool(np.allclose(right.camera_to_pixels(right.world_to_camera([0.6, 0.0, 2.0])),
        ...                  right.project([0.6, 0.0, 2.0])))
        True
        """
        pc = np.asarray(points_camera, float)
        z = pc[..., 2:3]
        with np.errstate(divide="ignore", invalid="ignore"):
            xn = np.where(z > 1e-9, pc[..., :2] / z, np.nan)
        return self.normalized_to_pixels(xn)

    def normalized_to_pixels(self, xn: np.ndarray) -> np.ndarray:
        """Distort normalised coordinates ``(..., 2)`` and map them to pixels."""
        xd = distort_normalized(xn, self.distortions)
        K = self.matrix
        u = K[0, 0] * xd[..., 0] + K[0, 1] * xd[..., 1] + K[0, 2]
        v = K[1, 1] * xd[..., 1] + K[1, 2]
        return np.stack([u, v], axis=-1)

    def pixels_to_normalized(self, pixels: np.ndarray) -> np.ndarray:
        """Undistorted normalised coordinates ``(..., 2)`` of pixels ``(..., 2)``.

        Inverts the pixel mapping, then the distortion model of eq. 3.7-3.9
        by fixed-point iteration (as OpenCV's ``undistortPoints``) finished
        with Gauss-Newton steps, to about 1e-12 in normalised units. NaN stays
        NaN.

        Examples
        --------
        With radial distortion the inverse still recovers the ideal coordinates:

        >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
        >>> lens = Camera("c", (640, 480), K, distortions=[-0.2, 0.0, 0.0, 0.0, 0.0])
        >>> lens.pixels_to_normalized(lens.project([0.3, 0.2, 2.0])).round(9)
        array([0.15, 0.1 ])
        """
        px = np.asarray(pixels, float)
        K = self.matrix
        yd = (px[..., 1] - K[1, 2]) / K[1, 1]
        xd = (px[..., 0] - K[0, 2] - K[0, 1] * yd) / K[0, 0]
        target = np.stack([xd, yd], axis=-1)
        k1, k2, p1, p2, k3 = self.distortions
        x = target.copy()
        for _ in range(30):  # fixed point: x = (xd - tangential(x)) / radial(x)
            r2 = x[..., 0] ** 2 + x[..., 1] ** 2
            radial = 1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3
            dx = 2 * p1 * x[..., 0] * x[..., 1] + p2 * (r2 + 2 * x[..., 0] ** 2)
            dy = p1 * (r2 + 2 * x[..., 1] ** 2) + 2 * p2 * x[..., 0] * x[..., 1]
            x = np.stack([(target[..., 0] - dx) / radial, (target[..., 1] - dy) / radial], axis=-1)
        eps = 1e-7
        for _ in range(3):  # Gauss-Newton polish with a numerical Jacobian
            f0 = distort_normalized(x, self.distortions) - target
            jx = (distort_normalized(x + [eps, 0], self.distortions) - target - f0) / eps
            jy = (distort_normalized(x + [0, eps], self.distortions) - target - f0) / eps
            det = jx[..., 0] * jy[..., 1] - jy[..., 0] * jx[..., 1]
            with np.errstate(divide="ignore", invalid="ignore"):
                step0 = (jy[..., 1] * f0[..., 0] - jy[..., 0] * f0[..., 1]) / det
                step1 = (-jx[..., 1] * f0[..., 0] + jx[..., 0] * f0[..., 1]) / det
            x = x - np.stack([step0, step1], axis=-1)
        return x

    def undistort_pixels(self, pixels: np.ndarray) -> np.ndarray:
        """Ideal (distortion-free) pixel coordinates of distorted pixels.

        Examples
        --------
        >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
        >>> lens = Camera("c", (640, 480), K, distortions=[-0.2, 0.0, 0.0, 0.0, 0.0])
        >>> distorted = lens.project([0.3, 0.2, 2.0])
        >>> distorted.round(2), lens.undistort_pixels(distorted).round(6)
        (array([439.22, 319.48]), array([440., 320.]))
        """
        xn = self.pixels_to_normalized(pixels)
        K = self.matrix
        u = K[0, 0] * xn[..., 0] + K[0, 1] * xn[..., 1] + K[0, 2]
        v = K[1, 1] * xn[..., 1] + K[1, 2]
        return np.stack([u, v], axis=-1)

    def rays(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World-frame ray origins and unit directions through pixels ``(..., 2)``.

        Examples
        --------
        >>> import numpy as np
        >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
        >>> left = Camera("left", (640, 480), K)
        >>> origin, direction = left.rays(np.array([320.0, 240.0]))   # the principal point
        >>> origin, direction
        (array([0., 0., 0.]), array([0., 0., 1.]))
        """
        xn = self.pixels_to_normalized(pixels)
        d_cam = np.concatenate([xn, np.ones(xn.shape[:-1] + (1,))], axis=-1)
        d = d_cam @ self.rotation_matrix  # R^T d for row vectors
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        return np.broadcast_to(self.center, d.shape).copy(), d

    def in_image(self, pixels: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Boolean mask: pixel lies inside the image by at least ``margin``.

        Examples
        --------
        >>> import numpy as np
        >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
        >>> left = Camera("left", (640, 480), K)
        >>> left.in_image(np.array([[10.0, 10.0], [700.0, 10.0]]))
        array([ True, False])
        """
        px = np.asarray(pixels, float)
        w, h = self.size
        with np.errstate(invalid="ignore"):
            return ((px[..., 0] >= -0.5 + margin) & (px[..., 0] <= w - 0.5 - margin)
                    & (px[..., 1] >= -0.5 + margin) & (px[..., 1] <= h - 0.5 - margin))


def rotation_matrix(rvec) -> np.ndarray:
    """Rotation matrix of a Rodrigues vector (angle = norm, axis = direction).

    Examples
    --------
    >>> import numpy as np
    >>> rotation_matrix([0.0, 0.0, np.pi / 2]).round(6)     # 90 degrees about z
    array([[ 0., -1.,  0.],
           [ 1.,  0.,  0.],
           [ 0.,  0.,  1.]])
    """
    r = np.asarray(rvec, float).reshape(3)
    theta = np.linalg.norm(r)
    if theta < 1e-15:
        return np.eye(3)
    k = r / theta
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(theta) * Kx + (1 - math.cos(theta)) * Kx @ Kx


def axis_rotations(axis: str, angles) -> np.ndarray:
    """Rotations about one coordinate axis, one per angle: ``(..., 3, 3)``.

    Parameters
    ----------
    axis : {"x", "y", "z"}
    angles : array_like
        Angles in radians (any shape; right-handed, as :func:`rotation_matrix`).

    Examples
    --------
    >>> import numpy as np
    >>> R = axis_rotations("z", [0.0, np.pi / 2])
    >>> R.shape, bool(np.allclose(R[1], rotation_matrix([0.0, 0.0, np.pi / 2])))
    ((2, 3, 3), True)
    """
    if axis not in ("x", "y", "z"):
        raise ValueError(f"axis: expected 'x', 'y' or 'z', got {axis!r}")
    a = np.asarray(angles, float)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    rows = {"x": ((o, z, z), (z, c, -s), (z, s, c)),
            "y": ((c, z, s), (z, o, z), (-s, z, c)),
            "z": ((c, -s, z), (s, c, z), (z, z, o))}[axis]
    return np.stack([np.stack(r, -1) for r in rows], -2)


def rotation_vector(R) -> np.ndarray:
    """Rodrigues vector of a rotation matrix (projected onto SO(3) first).

    Examples
    --------
    >>> import numpy as np
    >>> rotation_vector(rotation_matrix([0.0, 0.0, np.pi / 2])).round(6)
    array([0.      , 0.      , 1.570796])
    """
    R = np.asarray(R, float)
    U, _, Vt = np.linalg.svd(R)
    Rp = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
    rvec, _ = cv2.Rodrigues(Rp)
    return rvec.ravel()


def distort_normalized(xn: np.ndarray, kc: np.ndarray) -> np.ndarray:
    """Apply Bouguet/OpenCV distortion to normalised coordinates ``(..., 2)``.

    ``x_d = (1 + k1 r^2 + k2 r^4 + k3 r^6) x_n + dx`` with the tangential
    term ``dx = [2 p1 x y + p2 (r^2 + 2 x^2), p1 (r^2 + 2 y^2) + 2 p2 x y]``
    (thesis eq. 3.7-3.9).

    Examples
    --------
    >>> import numpy as np
    >>> distort_normalized(np.array([0.1, 0.0]), np.array([-0.2, 0.0, 0.0, 0.0, 0.0]))   # (1 - 0.2 r^2) x
    array([0.0998, 0.    ])
    """
    k1, k2, p1, p2, k3 = np.asarray(kc, float)
    x, y = xn[..., 0], xn[..., 1]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = radial * x + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = radial * y + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([xd, yd], axis=-1)


@dataclass(frozen=True)
class Rig:
    """Cameras sharing one world frame (the reference camera's).

    Parameters
    ----------
    cameras : tuple of Camera
        In session order; ``cameras[i].name`` are unique.
    metadata : dict
        The ``[metadata]`` table of ``rig.toml`` (e.g. ``adjusted``, ``error``).

    Examples
    --------
    >>> import numpy as np
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> left = Camera("left", (640, 480), K)
    >>> right = Camera("right", (640, 480), K, translation=[-0.5, 0.0, 0.0])   # 0.5 m to the right
    >>> rig = Rig((left, right))
    >>> rig.names, len(rig), rig.subset(["right"]).names
    (['left', 'right'], 2, ['right'])
    >>> rig.project(np.array([0.1, 0.0, 2.0]))
    {'left': array([360., 240.]), 'right': array([160., 240.])}
    """

    cameras: tuple[Camera, ...]
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "cameras", tuple(self.cameras))
        names = [c.name for c in self.cameras]
        if len(set(names)) != len(names):
            raise RigError(f"rig: camera names must be unique, got {names}")

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.cameras]

    def __getitem__(self, name: str) -> Camera:
        for c in self.cameras:
            if c.name == name:
                return c
        raise KeyError(f"rig has no camera {name!r}; it has {self.names}")

    def __iter__(self):
        return iter(self.cameras)

    def __len__(self):
        return len(self.cameras)

    def project(self, points_world: np.ndarray) -> dict[str, np.ndarray]:
        """Pixels of world points in every camera, keyed by camera name."""
        return {c.name: c.project(points_world) for c in self.cameras}

    def subset(self, names) -> "Rig":
        """A rig with only the named cameras, in the given order."""
        return Rig(tuple(self[n] for n in names), dict(self.metadata))


# ---------------------------------------------------------------------------
# rig.toml
# ---------------------------------------------------------------------------

def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise RigError(f"rig.toml: cannot write a value of type {type(v).__name__}")


def rig_to_toml(rig: Rig) -> str:
    """The text of ``rig.toml`` for a rig (aniposelib format).

    Examples
    --------
    >>> import numpy as np
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> left = Camera("left", (640, 480), K)
    >>> right = Camera("right", (640, 480), K, translation=[-0.5, 0.0, 0.0])   # 0.5 m to the right
    >>> rig = Rig((left, right))
    >>> print(rig_to_toml(rig).splitlines()[1])
    name = "left"
    """
    lines = []
    for i, cam in enumerate(rig.cameras):
        lines += [
            f"[cam_{i}]",
            f"name = {_toml_value(cam.name)}",
            f"size = {_toml_value(list(cam.size))}",
            f"matrix = {_toml_value(cam.matrix)}",
            f"distortions = {_toml_value(cam.distortions)}",
            f"rotation = {_toml_value(cam.rotation)}",
            f"translation = {_toml_value(cam.translation)}",
            "",
        ]
    lines.append("[metadata]")
    for k, v in rig.metadata.items():
        lines.append(f"{k} = {_toml_value(v)}")
    return "\n".join(lines) + "\n"


def write_rig(rig: Rig, path) -> Path:
    """Write ``rig.toml`` atomically (a temporary file renamed into place).

    Examples
    --------
    >>> import numpy as np
    >>> K = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    >>> left = Camera("left", (640, 480), K)
    >>> right = Camera("right", (640, 480), K, translation=[-0.5, 0.0, 0.0])   # 0.5 m to the right
    >>> rig = Rig((left, right))
    >>> import tempfile, pathlib
    >>> path = write_rig(rig, pathlib.Path(tempfile.mkdtemp()) / "rig.toml")
    >>> read_rig(path).names
    ['left', 'right']
    """
    return atomic_write_text(Path(path), rig_to_toml(rig))


def _field(table, key, path, section, shape=None):
    if key not in table:
        raise RigError(f"{path}: [{section}] has no field '{key}'")
    value = table[key]
    if shape is not None:
        try:
            arr = np.asarray(value, float)
        except (TypeError, ValueError):
            raise RigError(f"{path}: [{section}] field '{key}' must be numbers of shape {shape}, got {value!r}") from None
        if arr.shape != shape and not (key == "distortions" and arr.ndim == 1 and 4 <= arr.size <= 5):
            raise RigError(f"{path}: [{section}] field '{key}' must have shape {shape}, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise RigError(f"{path}: [{section}] field '{key}' must hold finite numbers, got {value!r}")
        return arr
    return value


def read_rig(path) -> Rig:
    """Read a ``rig.toml`` (aniposelib format); errors name the file and field.

    Examples
    --------
    See :func:`write_rig`.
    """
    path = Path(path)
    if not path.is_file():
        raise RigError(f"{path}: rig file not found")

    try:
        data = tomllib.loads(read_text_utf8(path, RigError))
    except tomllib.TOMLDecodeError as exc:
        raise RigError(f"{path}: not valid TOML ({exc})") from None
    cams = []
    for section, table in data.items():
        if section == "metadata" or not isinstance(table, dict):
            continue
        name = str(_field(table, "name", path, section))
        size = _field(table, "size", path, section, (2,))
        if np.any(size < 1) or np.any(size != np.round(size)):
            raise RigError(f"{path}: [{section}] field 'size' must be [width, height] in pixels (integers >= 1), "
                           f"got {table['size']!r}")
        matrix = _field(table, "matrix", path, section, (3, 3))
        if not (matrix[0, 0] > 0 and matrix[1, 1] > 0) or np.any(matrix[2] != [0, 0, 1]) or matrix[1, 0] != 0:
            raise RigError(f"{path}: [{section}] field 'matrix' must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] "
                           f"with fx, fy > 0 (a camera matrix), got {table['matrix']!r}")
        cams.append(Camera(
            name=name,
            size=(int(size[0]), int(size[1])),
            matrix=matrix,
            distortions=_field(table, "distortions", path, section, (5,)),
            rotation=_field(table, "rotation", path, section, (3,)),
            translation=_field(table, "translation", path, section, (3,)),
        ))
    if not cams:
        raise RigError(f"{path}: no camera tables ([cam_0], ...) found")
    return Rig(tuple(cams), dict(data.get("metadata", {})))
