"""Where a bench sweep of a coarse-sun-sensor head puts the Sun: rings of incidence around each face's normal.

Seed 000 tabulates every detector's current against the incidence angle from 0 to 90° in 5° steps (Table C.1,
digest §3.5) and asks for the response to be measured on a bench (digest §8.3 item 7: "angular sweeps from 0 to
90° per detector and per temperature"). A bench turns the whole head, so one direction lights up to three faces
at once; the sweep here is planned face by face and then merged:

* for each face, rings of incidence γ around its outward normal (:data:`calibration.css.head.NORMALS`) from 0 to
  the field's edge every `step_deg` (the edge itself the last ring), each ring at up to `around` azimuths ψ about
  the normal — fewer near the centre, where the ring is short: no closer than the step along the ring;
* ψ = 0 points to the body's +z on the four side faces and to +x on the top and bottom faces, so rings of
  neighbouring faces meet on the body's coordinate planes and a direction two faces share is one point;
* directions closer than :data:`SAME_DIRECTION` are merged, the first kept.

:func:`halton_directions` spreads check directions over the whole sphere (never on the rings: a quasi-random
sequence), the same ones every time.

Directions are body-frame zenith θ (from +z) and azimuth φ (from +x toward +y) [°], the project's convention
(DESIGN.md); a face other than +z faces the source at θ up to 180°.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from ..sequences import halton_points
from .head import FACES, NORMALS, vector_angles

#: Directions closer than this (a chord of unit vectors, about 2e-5°) are one direction
SAME_DIRECTION = 3e-7


def face_frame(face: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n, u, v): the face's outward normal and two axes across it; ψ = 0 along u (the body's +z on a side face,
    +x on the top and bottom), ψ = 90° along v = n × u."""
    n = np.array(NORMALS[face], float)
    u = np.array([1.0, 0.0, 0.0]) if abs(n[2]) > 0.5 else np.array([0.0, 0.0, 1.0])
    return n, u, np.cross(n, u)


def ring_incidences_deg(field_deg: float, step_deg: float, *, edge: bool = True) -> np.ndarray:
    """Incidence angles of the rings [°]: 0, step, 2·step … up to `field_deg`, and `field_deg` itself when the step
    does not reach it exactly (`edge`)."""
    if not (0 < field_deg <= 180 and step_deg > 0):
        raise ValueError(f"need 0 < field ≤ 180° and a positive step, got {field_deg}°, {step_deg}°")
    rings = np.arange(0.0, field_deg + 1e-9, step_deg)
    if edge and field_deg - rings[-1] > 1e-6:
        rings = np.append(rings, field_deg)
    return rings


def ring_count(incidence_deg: float, around: int, step_deg: float) -> int:
    """Azimuths on a ring of incidence γ: one at the centre, else `around`, fewer where the ring is so short that
    they would lie closer than `step_deg` apart (at least 3)."""
    if incidence_deg < 1e-9:
        return 1
    length = 2 * math.pi * math.sin(math.radians(incidence_deg)) / math.radians(step_deg)
    return int(min(around, max(3, round(length))))


def face_rings(face: str, incidences_deg, around: int, step_deg: float) -> np.ndarray:
    """Unit vectors of `face`'s rings: s = cos γ n + sin γ (cos ψ u + sin ψ v), ring after ring, shape (M, 3)."""
    n, u, v = face_frame(face)
    out = []
    for gamma in np.asarray(incidences_deg, float):
        k = ring_count(gamma, around, step_deg)
        psi = np.radians(np.arange(k) * 360.0 / k)
        g = math.radians(gamma)
        out.append(math.cos(g) * n + math.sin(g) * (np.cos(psi)[:, None] * u + np.sin(psi)[:, None] * v))
    return np.vstack(out)


def unique_directions(vectors) -> np.ndarray:
    """Indices of `vectors` (M, 3) with every direction closer than :data:`SAME_DIRECTION` to an earlier one left
    out, in their order."""
    vectors = np.asarray(vectors, float)
    keep = np.ones(len(vectors), bool)
    for i, j in sorted(cKDTree(vectors).query_pairs(SAME_DIRECTION)):
        if keep[i]:
            keep[j] = False  # i < j: the later one goes
    return np.flatnonzero(keep)


def sweep_vectors(field_deg: float = 88.0, step_deg: float = 5.0, around: int = 8, faces=FACES, *,
                  edge: bool = True) -> np.ndarray:
    """Every face's rings (module docstring), shared directions once: unit vectors, shape (M, 3), face by face."""
    rings = ring_incidences_deg(field_deg, step_deg, edge=edge)
    vectors = np.vstack([face_rings(face, rings, around, step_deg) for face in faces])
    return vectors[unique_directions(vectors)]


def sweep_directions(field_deg: float = 88.0, step_deg: float = 5.0, around: int = 8, faces=FACES, *,
                     edge: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sweep_vectors` as body-frame (zenith, azimuth) [°]; azimuth 0 at the poles."""
    zenith, azimuth = vector_angles(sweep_vectors(field_deg, step_deg, around, faces, edge=edge))
    return np.asarray(zenith, float), np.asarray(azimuth, float)


def sweep_size_bound(field_deg: float, step_deg: float, around: int, n_faces: int = len(FACES)) -> int:
    """An upper bound of :func:`sweep_vectors`' length from the numbers alone (before any is computed)."""
    return n_faces * (1 + int(math.floor(field_deg / step_deg + 1e-9)) * around + around)


def halton_directions(n: int, *, decimals: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """`n` directions spread evenly over the whole sphere: the Halton sequence in bases 2 and 3 mapped area-true
    (cos θ = 1 − 2u, φ = 360° v), rounded to `decimals` [°] (zenith, azimuth), the same every time."""
    u, v = halton_points(n).T
    zenith = np.degrees(np.arccos(np.clip(1.0 - 2.0 * u, -1.0, 1.0)))
    return np.round(zenith, decimals), np.round(360.0 * v, decimals) % 360.0
