"""The one typed home of the physical constants and defaults of the sensor and the bench.

Every other module takes these as arguments; none of them carries its own copy of a number such as
the 9.9 µm pixel pitch or the 136.2 mm lever arm.

References
----------
seed 003, §3.1 (sensor: 640×480 px, 9.9 µm pixels, L = 1.37 mm, 80 µm pinhole) and §4.1/eq. 8 (bench:
lever arm d = 136.2 mm, source distance L = 710 mm or 710 cm — [ambiguous] in the thesis, so it is a
parameter here and never a literal in code; 0.5° source).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class SensorDesign:
    """Nominal design of a CMOS pinhole sun sensor (seed 003 §3.1).

    Attributes
    ----------
    width_px, height_px : int
        Detector size [px]. 640×480 for the NOIL1SM0300A (LUPA300).
    pixel_pitch_mm : float
        Pixel pitch [mm]. 9.9 µm.
    pinhole_height_mm : float
        Nominal mask-to-matrix distance L [mm] (seed 003 eq. 6). 1.37 mm.
    hole_diameter_mm : float
        Pinhole diameter [mm]. 80 µm.
    bit_depth : int
        ADC resolution [bit]; a pixel saturates at 2**bit_depth − 1 DN. 10 for the LUPA300.
    fov_half_deg : float
        Half field of view [°]. 60° (120° FOV, seed 003 eq. 2).
    """

    width_px: int = 640
    height_px: int = 480
    pixel_pitch_mm: float = 0.0099
    pinhole_height_mm: float = 1.37
    hole_diameter_mm: float = 0.080
    bit_depth: int = 10
    fov_half_deg: float = 60.0

    def __post_init__(self) -> None:
        for name in ("width_px", "height_px", "bit_depth"):
            if getattr(self, name) <= 0:
                raise ValueError(f"`{name}` must be positive, got {getattr(self, name)}")
        for name in ("pixel_pitch_mm", "pinhole_height_mm", "hole_diameter_mm"):
            if not getattr(self, name) > 0:
                raise ValueError(f"`{name}` must be positive, got {getattr(self, name)}")
        if not 0 < self.fov_half_deg < 90:
            raise ValueError(f"`fov_half_deg` must lie in (0, 90), got {self.fov_half_deg}")

    @property
    def saturation_dn(self) -> int:
        """Full-scale pixel value [DN]."""
        return 2**self.bit_depth - 1

    @property
    def centre_px(self) -> tuple[float, float]:
        """Geometric centre of the detector in pixel coordinates (origin at the centre of pixel 0, 0)."""
        return (self.width_px - 1) / 2.0, (self.height_px - 1) / 2.0

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class BenchGeometry:
    """Geometry of a calibration bench with the zenith rotation axis offset from the sensor.

    Attributes
    ----------
    lever_arm_mm : float
        Distance d from the zenith rotation axis to the sensor [mm] (seed 003 eq. 8: 136.2 mm).
    source_distance_mm : float
        Distance L from the sensor to the sun simulator [mm]. Seed 003 states 710 mm at eq. 8 and 710 cm in
        §4.1 ([ambiguous]); the default follows eq. 8. Always pass the value measured on your bench.
    source_diameter_deg : float
        Angular diameter of the simulated sun seen from the sensor [°] (0.5°).
    lever_arm_sd_mm, source_distance_sd_mm : float or None
        1σ of the two lengths as measured on the bench [mm]; None when not stated. Eq. 8 does not use them:
        the joint fit of sensor and bench weighs the lengths by them
        (:meth:`calibration.stage_geometry.GeometryPrior.from_bench`).

    Notes
    -----
    This is the one geometry value of a bench: the run engine turns stage angles into body directions with
    it (:func:`calibration.stage_geometry.body_direction_deg`), the fits take their prior from it, and the
    bench file's ``geometry:`` section and the simulation's truth each build one. The fitted stage-angle
    model has its own parameters (:class:`calibration.stage_geometry.StageGeometry`: the ratio
    d / (L + d) and the stages' zero offsets), which no bench states.
    """

    lever_arm_mm: float = 136.2
    source_distance_mm: float = 710.0
    source_diameter_deg: float = 0.5
    lever_arm_sd_mm: float | None = None
    source_distance_sd_mm: float | None = None

    def __post_init__(self) -> None:
        if not self.lever_arm_mm >= 0:
            raise ValueError(f"`lever_arm_mm` must be >= 0, got {self.lever_arm_mm}")
        if not self.source_distance_mm > 0:
            raise ValueError(f"`source_distance_mm` must be positive, got {self.source_distance_mm}")
        if not 0 < self.source_diameter_deg < 10:
            raise ValueError(f"`source_diameter_deg` must lie in (0, 10), got {self.source_diameter_deg}")
        for name in ("lever_arm_sd_mm", "source_distance_sd_mm"):
            value = getattr(self, name)
            if value is not None and not value > 0:
                raise ValueError(f"`{name}` must be positive (or None), got {value}")

    def to_dict(self) -> dict:
        return asdict(self)


DEFAULT_SENSOR = SensorDesign()
DEFAULT_BENCH = BenchGeometry()

#: Full scale of seed 003's detector [DN]: the largest value of its 10-bit ADC (``DEFAULT_SENSOR.saturation_dn``,
#: 1023). Auto-exposure aims at a fraction of it and the centroid flags a spot that reaches it.
FULL_SCALE_DN = float(DEFAULT_SENSOR.saturation_dn)
