"""Registration of a marker model to measured markers: Horn's quaternion (thesis eq. 5.14-5.21).

The thesis (section 5.4) registers the static-shot model ``MM^m`` to the
measured markers of every frame with the closed-form solution of Horn (1987)
that Besl and McKay (1992) use: with the centred model ``x_m - mu_x`` and the
centred points ``p_m - mu_p``, the cross-covariance
``S = sum_m w_m (x_m - mu_x)(p_m - mu_p)^T`` gives Horn's symmetric 4 x 4
matrix ``Q(S)`` (eq. 5.17); the eigenvector of its largest eigenvalue is the
unit quaternion ``q_R = [q0 q1 q2 q3]`` of the optimal rotation (eq. 5.15).

These are the pieces that the thesis' registration (:func:`horsemocap.rigid.register`)
and the pose trajectory's weighted one (:func:`horsemocap.pose.register_pose`)
share. The rotation itself is handed to SciPy's
:class:`scipy.spatial.transform.Rotation`, the package's one rotation toolkit
(its quaternions are scalar-last, ``[q1 q2 q3 q0]``).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["skew", "check_model", "quaternion_from_cross_covariance", "rotation_from_cross_covariance"]


def skew(v) -> np.ndarray:
    """Cross-product matrices ``[v]x`` of vectors, so that ``[v]x u = v x u``.

    Parameters
    ----------
    v : (..., 3) array_like

    Returns
    -------
    (..., 3, 3) ndarray

    Examples
    --------
    >>> import numpy as np
    >>> skew([1.0, 2.0, 3.0]) @ np.array([0.0, 0.0, 1.0])
    array([ 2., -1.,  0.])
    """
    v = np.asarray(v, float)
    z = np.zeros(v.shape[:-1])
    return np.stack([
        np.stack([z, -v[..., 2], v[..., 1]], -1),
        np.stack([v[..., 2], z, -v[..., 0]], -1),
        np.stack([-v[..., 1], v[..., 0], z], -1),
    ], -2)


def check_model(model, n_markers: int) -> np.ndarray:
    """The static-shot model as a finite ``(n_markers, 3)`` array, or a clear error.

    Parameters
    ----------
    model : (m, 3) array_like
        The markers of the static shot (``MM^m``), in the order of the measured ones.
    n_markers : int
        How many markers the measured points have.

    Returns
    -------
    (n_markers, 3) ndarray

    Raises
    ------
    ValueError
        Naming ``model`` and the shape expected, or its NaN.

    Examples
    --------
    >>> check_model([[0, 0, 0], [1, 0, 0], [0, 1, 0]], 3).shape
    (3, 3)
    """
    x = np.asarray(model, float)
    if x.shape != (n_markers, 3):
        raise ValueError(f"model: expected shape ({n_markers}, 3) to match points, got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("model: static-shot markers contain NaN")
    return x


def quaternion_from_cross_covariance(S) -> np.ndarray:
    """Horn's unit quaternion (scalar first) of the rotation that best maps the model onto the points.

    ``S`` is the cross-covariance ``sum_m w_m xc_m pc_m^T`` of the centred
    model ``xc`` and points ``pc`` (eq. 5.14-5.21). With ``tr = trace(S)``,
    ``A = S - S^T`` and ``Delta = [A_23, A_31, A_12]^T``, Horn's symmetric
    matrix is (eq. 5.17)::

        Q(S) = | tr      Delta^T              |
               | Delta   S + S^T - tr I_3     |

    and the quaternion is the eigenvector of its largest eigenvalue.

    Parameters
    ----------
    S : (n, 3, 3) array_like

    Returns
    -------
    (n, 4) ndarray
        ``q_R = [q0 q1 q2 q3]`` (thesis order: scalar first), unit length, sign arbitrary.

    Examples
    --------
    Points that are the model turned by 90 degrees about z:

    >>> import numpy as np
    >>> model = np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1], [-1, -1, -1]])
    >>> points = model @ np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]).T
    >>> xc, pc = model - model.mean(0), points - points.mean(0)
    >>> q = quaternion_from_cross_covariance((xc.T @ pc)[None])[0]
    >>> np.round(q * np.sign(q[0]), 6) + 0.0       # cos 45 deg, 0, 0, sin 45 deg
    array([0.707107, 0.      , 0.      , 0.707107])
    """
    S = np.asarray(S, float)
    n = len(S)
    tr = np.trace(S, axis1=1, axis2=2)
    A = S - np.swapaxes(S, 1, 2)
    delta = np.stack([A[:, 1, 2], A[:, 2, 0], A[:, 0, 1]], -1)
    Q = np.zeros((n, 4, 4))
    Q[:, 0, 0] = tr
    Q[:, 0, 1:] = delta
    Q[:, 1:, 0] = delta
    Q[:, 1:, 1:] = S + np.swapaxes(S, 1, 2) - tr[:, None, None] * np.eye(3)
    _, vecs = np.linalg.eigh(Q)
    return vecs[:, :, -1]


def rotation_from_cross_covariance(S) -> Rotation:
    """Horn's optimal rotation (:func:`quaternion_from_cross_covariance`) as a SciPy ``Rotation``.

    The thesis writes the quaternion scalar first (``q_R = [q0 q1 q2 q3]``,
    eq. 5.15); SciPy's ``Rotation.from_quat`` takes it scalar last, so the
    scalar is moved to the end before it is handed over.

    Parameters
    ----------
    S : (n, 3, 3) array_like
        Cross-covariances of the centred model and points.

    Returns
    -------
    scipy.spatial.transform.Rotation
        ``n`` rotations ``R`` with ``p - mu_p = R (x - mu_x)`` at best.

    Examples
    --------
    >>> import numpy as np
    >>> model = np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1], [-1, -1, -1]])
    >>> turn = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])      # 90 deg about z
    >>> points = model @ turn.T
    >>> xc, pc = model - model.mean(0), points - points.mean(0)
    >>> R = rotation_from_cross_covariance((xc.T @ pc)[None]).as_matrix()[0]
    >>> bool(np.allclose(R, turn))
    True
    """
    q = quaternion_from_cross_covariance(S)
    return Rotation.from_quat(np.column_stack([q[:, 1:], q[:, 0]]))
