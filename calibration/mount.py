"""From a two-axis table's angles to the Sun's (α, β) on the sensor, and back: planning a ±40° × ±40° grid.

The thesis compares the sensor's angles with "the known rotation angles of the table" as if they were the
same (§3.1, Φ). They are not: eq. 2.2's angles are projections (tan α = s_x/s_z, tan β = s_y/s_z) and a
two-axis table turns the sensor about two axes in sequence. With the outer axis at a and the inner at b the
Sun arrives along s = (sin a, sin b cos a, cos a cos b), so β = b but tan α = tan a / cos b: at a = b = 40°
the table says 40° and the sensor sees α = 47.6° (digest §7 item 9). Two kinds of table are modelled:

* the seed 003 bench, **azimuth-on-zenith**: a zenith stage Ω tilts the boresight away from the source, an
  azimuth stage φ_s on top turns the sensor about its boresight; the Sun sits at zenith Ω, azimuth φ_s
  (:func:`calibration.stage_geometry.body_vectors_from_stage`, with its lever arm, zeros and source
  elevation);
* an **alt-az fork** mount, **zenith-on-azimuth** (Meade LX200 style): an outer vertical azimuth axis A and an
  inner altitude axis E carry the sensor, its boresight on the source at A = E = 0, its x axis horizontal;
  then a = ±(A − A0), b = ±(E − E0) as above (:class:`ForkMount`).

Each has its forward map (table → s → (α, β)) and its exact inverse (the table angles that put the Sun at a
wanted (α, β)), so a grid planned in (α, β) is set on the table exactly.

References
----------
seed 002, §3.1 (Φ against the table's angles), §3.2.1 (MEADE two-axis table); digest §7 item 9; seed 003,
eq. 8 and Fig. 4.5 (the azimuth-on-zenith bench).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import CalibrationError
from .qd.angles import projection_angles_from_vector, vector_from_projection_angles
from .stage_geometry import StageGeometry, body_vectors_from_stage


@dataclass(frozen=True)
class ForkMount:
    """An alt-az fork mount carrying the sensor (zenith-on-azimuth).

    Attributes
    ----------
    azimuth_sign, altitude_sign : float
        +1 or −1: the sense in which a positive reading moves the Sun toward the sensor's +x (azimuth) and
        +y (altitude). With +1 a reading (A, E) puts the Sun at a = A, b = E.
    azimuth_zero_deg, altitude_zero_deg : float
        Readings at which the boresight points at the source [°].
    roll_deg : float
        The sensor's turn about its boresight on the mount: its +x axis is `roll_deg` from the altitude axis
        [°].
    arm_ratio : float
        q = L / (L + D) for a sensor L out from the axes' crossing along its boresight and a source D beyond
        it (:func:`calibration.stage_geometry.arm_ratio`): the parallax of a source at a finite distance, as
        seed 003 eq. 8 has it for the two-stage table. 0: a source at infinity, or the sensor on the axes.
    """

    azimuth_sign: float = 1.0
    altitude_sign: float = 1.0
    azimuth_zero_deg: float = 0.0
    altitude_zero_deg: float = 0.0
    roll_deg: float = 0.0
    arm_ratio: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.arm_ratio < 1.0:
            raise ValueError(f"`arm_ratio` must lie in [0, 1), got {self.arm_ratio}")
        if abs(self.azimuth_sign) != 1.0 or abs(self.altitude_sign) != 1.0:
            raise ValueError("`azimuth_sign` and `altitude_sign` must be +1 or −1")


def _rot_z(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def fork_vectors(azimuth_deg, altitude_deg, mount: ForkMount = ForkMount()) -> np.ndarray:
    """Unit Sun vectors in the body frame for fork-mount readings (A, E).

    .. math:: s = R_z(ψ)^T (\\sin a,\\; \\sin b \\cos a,\\; \\cos a \\cos b),
              \\quad a = ±(A - A_0),\\; b = ±(E - E_0)

    With a lever arm (``mount.arm_ratio`` q > 0) the sensor moves as the mount turns and the source, at a
    finite distance, is seen along v − q ẑ (normalised) instead of v, the parallax of seed 003 eq. 8.

    References
    ----------
    digest §7 item 9 (the two-axis kinematics); seed 002 §3.2.1 (the MEADE table).
    """
    a = np.radians(mount.azimuth_sign * (np.asarray(azimuth_deg, float) - mount.azimuth_zero_deg))
    b = np.radians(mount.altitude_sign * (np.asarray(altitude_deg, float) - mount.altitude_zero_deg))
    a, b = np.broadcast_arrays(a, b)
    plate = np.stack([np.sin(a), np.sin(b) * np.cos(a), np.cos(a) * np.cos(b)], axis=-1)
    if mount.arm_ratio:
        plate = plate - np.array([0.0, 0.0, mount.arm_ratio])
        plate = plate / np.linalg.norm(plate, axis=-1, keepdims=True)
    return plate @ _rot_z(mount.roll_deg)  # rows: R_z(ψ)ᵀ v


def fork_for_vectors(s, mount: ForkMount = ForkMount()) -> tuple[np.ndarray, np.ndarray]:
    """Fork readings (A, E) [°] that bring the Sun to body vectors `s` (inverse of :func:`fork_vectors`).

    References
    ----------
    digest §7 item 9 (inverted: a = asin(s_x), b = atan2(s_y, s_z) on the mount's plate).
    """
    s = np.asarray(s, float)
    v = s @ _rot_z(mount.roll_deg).T  # R_z(ψ) s
    v = v / np.linalg.norm(v, axis=-1, keepdims=True)
    if mount.arm_ratio:  # undo the parallax: the unit v0 with v0 − q ẑ along v
        q = mount.arm_ratio
        t = -q * v[..., 2] + np.sqrt(1.0 - q * q * (1.0 - v[..., 2] ** 2))
        v = t[..., None] * v + np.array([0.0, 0.0, q])
    a = np.degrees(np.arcsin(np.clip(v[..., 0], -1.0, 1.0)))
    b = np.degrees(np.arctan2(v[..., 1], v[..., 2]))
    return a / mount.azimuth_sign + mount.azimuth_zero_deg, b / mount.altitude_sign + mount.altitude_zero_deg


def table_vectors(stage_azimuth_deg, stage_zenith_deg, geometry: StageGeometry = StageGeometry(0.0)) -> np.ndarray:
    """Unit Sun vectors in the body frame for the seed 003 azimuth-on-zenith table's readings (φ_s, Ω).

    References
    ----------
    seed 003, eq. 8 (:func:`calibration.stage_geometry.body_vectors_from_stage`).
    """
    return body_vectors_from_stage(stage_azimuth_deg, stage_zenith_deg, geometry)


def _tangents(s):
    s = np.asarray(s, float)
    return np.stack([s[..., 0] / s[..., 2], s[..., 1] / s[..., 2]], axis=-1)


def table_for_vectors(s, geometry: StageGeometry = StageGeometry(0.0), *, iterations: int = 30,
                      tolerance: float = 1e-13) -> tuple[np.ndarray, np.ndarray]:
    """Seed 003 table readings (φ_s, Ω) [°] that bring the Sun to body vectors `s` (s_z > 0).

    Exact in closed form for the ideal bench (φ_s = azimuth, Ω = zenith, or with the lever arm alone
    Ω = θ − asin(q sin θ)); with the stage zero, the source's elevation or a fixture tilt, Newton steps on the
    Sun's tangents in the Cartesian stage coordinates (Ω' cos φ_s, Ω' sin φ_s), which stay regular at the
    boresight. φ_s is returned in [0, 360), Ω − Ω0 ≥ 0; NaN where no reading reaches the direction (with
    the source an angle η out of the zenith stage's plane the azimuth stage keeps the Sun about η from the
    boresight).

    References
    ----------
    seed 003, eq. 8 (inverted); :mod:`calibration.stage_geometry`.
    """
    s = np.asarray(s, float)
    s = s / np.linalg.norm(s, axis=-1, keepdims=True)
    if np.any(s[..., 2] <= 0):
        raise CalibrationError("the table can only be planned for Suns in front of the sensor (s_z > 0)")
    theta = np.arccos(np.clip(s[..., 2], -1.0, 1.0))
    phi = np.arctan2(s[..., 1], s[..., 0])
    omega = theta - np.arcsin(np.clip(geometry.arm_ratio * np.sin(theta), -1.0, 1.0))
    u, v = omega * np.cos(phi), omega * np.sin(phi)
    target = _tangents(s)

    def tangents(u_, v_):
        om, ph = np.hypot(u_, v_), np.arctan2(v_, u_)
        return _tangents(body_vectors_from_stage(np.degrees(ph), np.degrees(om) + geometry.zenith_zero_deg, geometry))

    for _ in range(iterations):
        f = tangents(u, v) - target
        if np.all(np.abs(f) < tolerance):
            break
        h = 1e-7
        ju = (tangents(u + h, v) - tangents(u - h, v)) / (2 * h)
        jv = (tangents(u, v + h) - tangents(u, v - h)) / (2 * h)
        det = ju[..., 0] * jv[..., 1] - ju[..., 1] * jv[..., 0]
        du = -(jv[..., 1] * f[..., 0] - jv[..., 0] * f[..., 1]) / det
        dv = -(-ju[..., 1] * f[..., 0] + ju[..., 0] * f[..., 1]) / det
        u, v = u + du, v + dv
    reached = np.all(np.abs(tangents(u, v) - target) < 1e-9, axis=-1)
    om, ph = np.hypot(u, v), np.arctan2(v, u)
    return (np.where(reached, np.mod(np.degrees(ph), 360.0), np.nan),
            np.where(reached, np.degrees(om) + geometry.zenith_zero_deg, np.nan))


def mount_vectors(angle1_deg, angle2_deg, mount) -> np.ndarray:
    """Body-frame Sun vectors for readings of `mount`: a :class:`ForkMount` (A, E) or a seed 003
    :class:`~calibration.stage_geometry.StageGeometry` (φ_s, Ω).

    References
    ----------
    digest §7 item 9; seed 003, eq. 8.
    """
    if isinstance(mount, ForkMount):
        return fork_vectors(angle1_deg, angle2_deg, mount)
    if isinstance(mount, StageGeometry):
        return table_vectors(angle1_deg, angle2_deg, mount)
    raise TypeError(f"`mount` must be a ForkMount or a StageGeometry, got {type(mount).__name__}")


def mount_projection(angle1_deg, angle2_deg, mount) -> tuple[np.ndarray, np.ndarray]:
    """(α, β) [°] of the Sun on the sensor for readings of `mount` (see :func:`mount_vectors`).

    References
    ----------
    seed 002, eq. 2.2 (the projection angles); digest §7 item 9.
    """
    return projection_angles_from_vector(mount_vectors(angle1_deg, angle2_deg, mount))


def mount_for_projection(alpha_deg, beta_deg, mount, *, unreachable: str = "raise") -> tuple[np.ndarray, np.ndarray]:
    """Readings of `mount` that put the Sun at (α, β) on the sensor: (A, E) for a fork, (φ_s, Ω) for the
    seed 003 table.

    A direction no reading reaches raises a :class:`~calibration.errors.CalibrationError` naming it
    (``unreachable="nan"``: NaN readings instead).

    References
    ----------
    seed 002, eq. 2.2; digest §7 item 9 and §4 (a grid over ±40° needs the table kinematics).
    """
    s = vector_from_projection_angles(alpha_deg, beta_deg)
    if isinstance(mount, ForkMount):
        return fork_for_vectors(s, mount)
    if not isinstance(mount, StageGeometry):
        raise TypeError(f"`mount` must be a ForkMount or a StageGeometry, got {type(mount).__name__}")
    first, second = table_for_vectors(s, mount)
    missed = ~np.isfinite(first)
    if missed.any() and unreachable == "raise":
        i = int(np.flatnonzero(missed.ravel())[0])
        a, b = np.broadcast_arrays(np.asarray(alpha_deg, float), np.asarray(beta_deg, float))
        raise CalibrationError(
            f"{int(missed.sum())} direction(s) cannot be set on the table, the first (α, β) = ({a.ravel()[i]:g}°, "
            f"{b.ravel()[i]:g}°): with the source {mount.source_elevation_deg:g}° out of the zenith stage's plane "
            "the azimuth stage keeps the Sun about that far from the boresight")
    return first, second


def projection_grid(half_width_deg: float = 40.0, step_deg: float = 5.0, *, checkpoints: bool = True) -> dict:
    """A square grid of (α, β) nodes and, optionally, check points midway between them.

    Returns
    -------
    dict
        ``alpha_deg``, ``beta_deg`` (flattened, α-major) and ``check`` (True for the points at the centres
        of the grid's cells, which a calibration must never fit: seed 002 §5.3 warns the error between nodes
        may exceed the error at them).

    References
    ----------
    seed 002, §5.2–5.3 (±40° field; error between the polynomial's nodes); digest §4 (grid, step, check
    points are the application's choice).
    """
    if not (half_width_deg > 0 and step_deg > 0):
        raise ValueError("`half_width_deg` and `step_deg` must be positive")
    n = int(round(half_width_deg / step_deg))
    nodes = np.linspace(-n * step_deg, n * step_deg, 2 * n + 1)
    a, b = np.meshgrid(nodes, nodes, indexing="ij")
    alpha, beta, check = [a.ravel()], [b.ravel()], [np.zeros(a.size, bool)]
    if checkpoints and n > 0:
        mids = 0.5 * (nodes[1:] + nodes[:-1])
        ca, cb = np.meshgrid(mids, mids, indexing="ij")
        alpha.append(ca.ravel())
        beta.append(cb.ravel())
        check.append(np.ones(ca.size, bool))
    return {"alpha_deg": np.concatenate(alpha), "beta_deg": np.concatenate(beta), "check": np.concatenate(check)}
