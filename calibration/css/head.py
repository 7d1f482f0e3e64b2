"""The coarse-sun-sensor (CSS) head of seed 000: its faces, detectors, channel names and frames.

A head is a cube (seed 000's PilsenCUBE) with a triplet of detectors at the centre of each face: an EPD-365 UV
photodiode (``uv``), a BPW 21 visible photodiode (``vis``) and a TPS 230 thermopile (``ir``), digest §3.1.

Faces are named by their outward normal in the head's body frame (``px`` = +X … ``mz`` = −Z) and carry the
thesis' numbers (seed 000 ch. 5.3.1, digest §5.3): face 1 faces the observer (+X), face 2 is the next side face
counter-clockwise (+Y), 3 is opposite 1 (−X), 4 opposite 2 (−Y), 5 the top (+Z), 6 the bottom (−Z).

Directions follow the project's convention (DESIGN.md): zenith θ from +Z, azimuth φ from +X towards +Y,
n = (sin θ cos φ, sin θ sin φ, cos θ). The thesis' [azimuth, elevation] are then az = φ, el = 90° − θ
(face 1's centre is [0, 0], face 5's [0, +90]).

Channels are ``<face>_<detector>`` in face order, then detector order (``px_uv``, ``px_vis``, ``px_ir``, ``py_uv``
…); a channel's CSV column adds its unit: ``_a`` for the photodiodes' currents, ``_v`` for the thermopile's
voltage (``px_uv_a``, ``px_vis_a``, ``px_ir_v``).
"""

from __future__ import annotations

import numpy as np

from ..geometry import direction_vector, zenith_azimuth_from_vector

#: Faces in the thesis' order 1 … 6
FACES: tuple[str, ...] = ("px", "py", "mx", "my", "pz", "mz")

#: The thesis' face number of each face (seed 000 ch. 5.3.1)
THESIS_NUMBER: dict[str, int] = {face: i + 1 for i, face in enumerate(FACES)}

#: Outward unit normal of each face in the body frame
NORMALS: dict[str, tuple[float, float, float]] = {
    "px": (1.0, 0.0, 0.0), "py": (0.0, 1.0, 0.0), "mx": (-1.0, 0.0, 0.0),
    "my": (0.0, -1.0, 0.0), "pz": (0.0, 0.0, 1.0), "mz": (0.0, 0.0, -1.0),
}

#: Detector types of a face's triplet: EPD-365 (UV photodiode), BPW 21 (visible photodiode), TPS 230 (thermopile)
DETECTORS: tuple[str, ...] = ("uv", "vis", "ir")

#: The unit each detector type's reading is in: amperes (photodiodes, photovoltaic mode) or volts (thermopile)
UNITS: dict[str, str] = {"uv": "a", "vis": "a", "ir": "v"}

#: Every channel, face-major: px_uv, px_vis, px_ir, py_uv …
CHANNELS: tuple[str, ...] = tuple(f"{face}_{detector}" for face in FACES for detector in DETECTORS)


def channel(face: str, detector: str) -> str:
    """The channel name of `detector` on `face` (ValueError naming the known ones otherwise)."""
    if face not in FACES:
        raise ValueError(f"no face {face!r} (faces: {', '.join(FACES)})")
    if detector not in DETECTORS:
        raise ValueError(f"no detector type {detector!r} (types: {', '.join(DETECTORS)})")
    return f"{face}_{detector}"


def split_channel(name: str) -> tuple[str, str]:
    """(face, detector) of a channel name such as ``py_vis``."""
    face, _, detector = name.partition("_")
    channel(face, detector)
    return face, detector


def column(name: str) -> str:
    """The CSV column of channel `name`: ``px_vis`` → ``px_vis_a``, ``px_ir`` → ``px_ir_v``."""
    return f"{name}_{UNITS[split_channel(name)[1]]}"


COLUMNS: tuple[str, ...] = tuple(column(c) for c in CHANNELS)


def normal_matrix(faces=FACES) -> np.ndarray:
    """Nominal outward normals of `faces` as rows, shape (len(faces), 3)."""
    return np.array([NORMALS[f] for f in faces], float)


def sun_vectors(zenith_deg, azimuth_deg) -> np.ndarray:
    """Unit sun vectors in the body frame from zenith and azimuth [°], shape (..., 3)."""
    return direction_vector(zenith_deg, azimuth_deg)


def incidence_deg(normals, vectors) -> np.ndarray:
    """Incidence angle [°] of each direction on each face: arccos(n·s), shape (..., n_faces).

    `normals` (n_faces, 3) unit normals; `vectors` (..., 3) unit directions. 90° and more: the face is not lit.
    """
    cosines = np.asarray(vectors, float) @ np.asarray(normals, float).T
    return np.degrees(np.arccos(np.clip(cosines, -1.0, 1.0)))


def thesis_az_el(zenith_deg, azimuth_deg) -> tuple[np.ndarray, np.ndarray]:
    """The thesis' [azimuth, elevation] [°] (digest §5.3) of body-frame zenith and azimuth [°]: az in [0, 360)."""
    return np.mod(np.asarray(azimuth_deg, float), 360.0), 90.0 - np.asarray(zenith_deg, float)


def from_thesis_az_el(az_deg, el_deg) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame (zenith, azimuth) [°] of the thesis' [azimuth, elevation] [°]."""
    return 90.0 - np.asarray(el_deg, float), np.mod(np.asarray(az_deg, float), 360.0)


def vector_angles(vectors) -> tuple[np.ndarray, np.ndarray]:
    """(zenith, azimuth) [°] of body-frame vectors (need not be unit)."""
    return zenith_azimuth_from_vector(vectors)
