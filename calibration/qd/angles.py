"""The thesis' two Sun angles (α, β) and the project's body frame (seed 002 eq. 2.2, seed 003 eq. 12).

The body frame is the CMOS family's: +z is the boresight and the Sun is
s = (sin z cos a, sin z sin a, cos z) for zenith z and azimuth a (:func:`calibration.geometry.direction_vector`).
Eq. 2.2 gives projection angles: tan α = s_x / s_z and tan β = s_y / s_z (digest §2.3, [DERIVED] there
from the spot-to-pinhole vector pointing at the Sun). Both are defined on the front hemisphere (s_z > 0).
"""

from __future__ import annotations

import numpy as np

from ..geometry import direction_vector, zenith_azimuth_from_vector


def projection_angles_from_vector(s) -> tuple[np.ndarray, np.ndarray]:
    """Projection angles α = atan2(s_x, s_z), β = atan2(s_y, s_z) of body-frame vectors [°].

    Parameters
    ----------
    s : array_like, shape (..., 3)
        Sun directions (any length) in the body frame.

    Returns
    -------
    alpha_deg, beta_deg : ndarray
        [°], in (−90, 90) for s_z > 0.

    References
    ----------
    seed 002, eq. 2.2 (digest §2.3: tan α = s_x/s_z, tan β = s_y/s_z).
    """
    s = np.asarray(s, dtype=float)
    return np.degrees(np.arctan2(s[..., 0], s[..., 2])), np.degrees(np.arctan2(s[..., 1], s[..., 2]))


def vector_from_projection_angles(alpha_deg, beta_deg) -> np.ndarray:
    """Unit body-frame vectors s = normalize(tan α, tan β, 1), inverse of :func:`projection_angles_from_vector`.

    Parameters
    ----------
    alpha_deg, beta_deg : numeric
        Projection angles [°], each in (−90, 90).

    Returns
    -------
    s : ndarray, shape (..., 3)

    References
    ----------
    seed 002, eq. 2.2 (digest §2.3, the unit Sun vector).
    """
    ta = np.tan(np.radians(np.asarray(alpha_deg, dtype=float)))
    tb = np.tan(np.radians(np.asarray(beta_deg, dtype=float)))
    ta, tb = np.broadcast_arrays(ta, tb)
    v = np.stack([ta, tb, np.ones_like(ta)], axis=-1)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def projection_angles(zenith_deg, azimuth_deg) -> tuple[np.ndarray, np.ndarray]:
    """(α, β) of the Sun at zenith z and azimuth a of the body frame [°].

    .. math:: \\tan α = \\tan z \\cos a, \\qquad \\tan β = \\tan z \\sin a

    References
    ----------
    seed 002, eq. 2.2; seed 003, eq. 12 (the body frame).
    """
    return projection_angles_from_vector(direction_vector(zenith_deg, azimuth_deg))


def zenith_azimuth_from_projection(alpha_deg, beta_deg) -> tuple[np.ndarray, np.ndarray]:
    """Zenith and azimuth [°] of the Sun at projection angles (α, β); azimuth in [0, 360), 0 at the boresight.

    References
    ----------
    seed 002, eq. 2.2 (inverted); seed 003, eq. 12.
    """
    return zenith_azimuth_from_vector(vector_from_projection_angles(alpha_deg, beta_deg))


def angle_between_projections_deg(alpha_a_deg, beta_a_deg, alpha_b_deg, beta_b_deg) -> np.ndarray:
    """Angle between the directions (α_a, β_a) and (α_b, β_b) [°], as atan2(|a × b|, a · b).

    References
    ----------
    seed 003, eq. 13 (the angular error), on seed 002's angles.
    """
    a = vector_from_projection_angles(alpha_a_deg, beta_a_deg)
    b = vector_from_projection_angles(alpha_b_deg, beta_b_deg)
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)))
