"""Project-wide rules of ../shared/DESIGN.md that a test can hold.

Imports are read with `ast`, never by importing the module: `import`, `from … import` at any depth (module
level, inside functions, under ``if TYPE_CHECKING``), relative imports resolved to their package, and
`importlib.import_module("…")` of a constant name.
"""

import ast
import importlib
import importlib.util
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


# --------------------------------------------------------------------------------------------------------
# Reading a module's imports
# --------------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Import:
    module: str  # the dotted module imported (a relative import resolved to its package)
    line: int
    names: tuple[str, ...] = ()  # `from module import names`; () for `import module`


def _where(path: Path, root: Path | None = None) -> str:
    try:
        return path.relative_to(root or ROOT).as_posix()
    except ValueError:
        return str(path)


def _package_of(path: Path, root: Path) -> tuple[str, ...]:
    """The package a module sits in (its folder, namespace packages included), as dotted parts."""
    try:
        return path.resolve().parent.relative_to(root.resolve()).parts
    except ValueError:
        return ()


def _import_records(path: Path, root: Path | None = None) -> list[_Import]:
    """Every import statement of the module at `path`, at any depth."""
    root = root or ROOT
    tree = ast.parse(path.read_text(), filename=str(path))
    package = _package_of(path, root)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [_Import(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = tuple(a.name for a in node.names)
            if node.level == 0:
                out.append(_Import(node.module or "", node.lineno, names))
                continue
            up = node.level - 1
            assert up < len(package), (f"{_where(path, root)}:{node.lineno}: relative import "
                                        f"{'.' * node.level}{node.module or ''} climbs above the project root")
            base = list(package[:len(package) - up]) + (node.module.split(".") if node.module else [])
            out.append(_Import(".".join(base), node.lineno, names))
        elif (isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant)
              and isinstance(node.args[0].value, str)
              and (getattr(node.func, "attr", None) or getattr(node.func, "id", None)) in ("import_module",
                                                                                            "__import__")):
            out.append(_Import(node.args[0].value, node.lineno))
    return out


def _is_module(dotted: str, root: Path) -> bool:
    target = root.joinpath(*dotted.split("."))
    return target.with_suffix(".py").is_file() or target.is_dir()


def _imported_modules(path: Path, root: Path | None = None) -> list[tuple[str, int]]:
    """(dotted module, line) for everything the module imports. `from pkg import name` counts as
    `pkg.name` when that is a module of the project (so `from calibration import design` is
    `calibration.design`), else as `pkg`."""
    root = root or ROOT
    out = []
    for imp in _import_records(path, root):
        subs = [f"{imp.module}.{n}" for n in imp.names
                if n != "*" and imp.module and _is_module(f"{imp.module}.{n}", root)]
        if len(subs) == len(imp.names) and subs:
            out += [(s, imp.line) for s in subs]
        else:
            out += [(imp.module, imp.line)] + [(s, imp.line) for s in subs]
    return [(m, line) for m, line in out if m]


def _imports(path: Path, root: Path | None = None) -> set[str]:
    """The top-level packages a module imports (at any depth of the module, relative imports resolved,
    and `importlib.import_module("...")` of a constant name)."""
    return {m.split(".")[0] for m, _ in _imported_modules(path, root)}


def _py_files(folder: str):
    return sorted(p for p in (ROOT / folder).rglob("*.py") if "__pycache__" not in p.parts)


def _under(module: str, allowed: str) -> bool:
    return module == allowed or module.startswith(allowed + ".")


# --------------------------------------------------------------------------------------------------------
# 1. Every layer's imports, as one table (DESIGN.md "Layers and the way data flows"; README "Layout")
# --------------------------------------------------------------------------------------------------------

#: The project's packages a layer may import (a module or a dotted prefix of one). Tests are exempt.
ALLOWED_IMPORTS = {
    # pure numerics, usable as a library on its own: nothing else of the project
    "calibration": ("calibration",),
    # drivers know nothing of campaigns and never share the fit's physics. Of calibration/ they may read only
    # `calibration.design`, the one typed configuration that holds every physical constant and default
    # (DESIGN.md "Conventions": never scattered as literals): the simulated world takes the bench geometry and
    # the detector from it. Anything else of calibration/ in drivers/ is a named exception below.
    "drivers": ("drivers", "calibration.design"),
    # the run engine talks to devices through driver interfaces and calls the pure functions; never web, cli
    "bench": ("bench", "calibration", "drivers"),
    # the dashboard renders what bench/ and calibration/ return; never the command line
    "web": ("web", "bench", "calibration", "drivers"),
    # the composition root (README "Layout"): may see everything
    "cli": ("bench", "calibration", "cli", "drivers", "web"),
}

#: Imports that break the table, each named with the reason it stands. A listed import that is gone fails
#: `test_every_import_exception_is_still_needed`, so the list never outlives its reason.
IMPORT_EXCEPTIONS = {
    ("drivers/sim/cmos_sensor.py", "calibration.centroid"):
        # The simulated CMOS module's on-board firmware finds the spot (its "centroid" command, seed 003 §3.3)
        # and the real module's firmware runs the same seed 003 algorithm, so the simulator calls the library's
        # `find_spot` rather than a second copy of it. It is the device's signal processing, not the fit's
        # forward model (the image itself comes from drivers/sim/raytrace.py), so no calibration is measured
        # against itself; the bench's own reading path centroids the raw frame on the host.
        "the simulated module's on-board firmware centroid is the seed 003 centroid of calibration/",
}

#: calibration/'s third-party imports: numerics only (stdlib aside). OpenCV is used there as array numerics
#: (medianBlur, dilate, moments in calibration/centroid.py; projectPoints in calibration/camera/), never for files or
#: cameras (checked below). pvlib is NREL's Solar Position Algorithm, the field's reference Sun
#: (calibration/field/), a pure function of time and site.
CALIBRATION_THIRD_PARTY = {"numpy", "scipy", "cv2", "pvlib"}
CV2_IO = {"imread", "imwrite", "imdecode", "imencode", "VideoCapture", "VideoWriter", "imshow", "namedWindow"}


def _project_packages() -> set[str]:
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    return {p.rstrip("*") for p in pyproject["tool"]["setuptools"]["packages"]["find"]["include"]}


def _layer_violations(layer: str) -> list[str]:
    project = _project_packages()
    found = []
    for path in _py_files(layer):
        where = _where(path)
        for module, line in _imported_modules(path):
            if module.split(".")[0] not in project or (where, module) in IMPORT_EXCEPTIONS:
                continue
            if not any(_under(module, a) for a in ALLOWED_IMPORTS[layer]):
                found.append(f"{where}:{line} imports {module} ({layer}/ may import only "
                             f"{', '.join(ALLOWED_IMPORTS[layer])} of the project)")
    return found


def test_the_import_table_has_a_row_for_every_package():
    """A new top-level package gets a row of its own, or the layer rules would not see it."""
    assert set(ALLOWED_IMPORTS) == _project_packages(), (
        f"pyproject's packages {sorted(_project_packages())} vs ALLOWED_IMPORTS rows {sorted(ALLOWED_IMPORTS)}")


@pytest.mark.parametrize("layer", sorted(ALLOWED_IMPORTS))
def test_each_layer_imports_only_what_the_table_allows(layer):
    violations = _layer_violations(layer)
    assert not violations, "\n".join(violations)


def test_every_import_exception_is_still_needed():
    for (where, module), reason in IMPORT_EXCEPTIONS.items():
        path = ROOT / where
        assert path.is_file(), f"IMPORT_EXCEPTIONS names {where}, which is gone: drop the exception ({reason})"
        imported = {m for m, _ in _imported_modules(path)}
        assert module in imported, (f"{where} no longer imports {module}: drop it from IMPORT_EXCEPTIONS")
        layer = where.split("/")[0]
        assert not any(_under(module, a) for a in ALLOWED_IMPORTS[layer]), (
            f"{where} -> {module} is allowed by the table anyway: drop it from IMPORT_EXCEPTIONS")


def test_calibration_imports_only_numerics():
    allowed = set(sys.stdlib_module_names) | CALIBRATION_THIRD_PARTY | {"calibration"}
    bad = []
    for path in _py_files("calibration"):
        bad += [f"{_where(path)}:{line} imports {m} (calibration/ takes numpy, scipy, cv2 and the standard library)"
                for m, line in _imported_modules(path) if m.split(".")[0] not in allowed]
        tree = ast.parse(path.read_text())
        bad += [f"{_where(path)}:{n.lineno} calls cv2.{n.attr} (I/O: calibration/ does none)"
                for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr in CV2_IO
                and isinstance(n.value, ast.Name) and n.value.id == "cv2"]
    assert not bad, "\n".join(bad)


def test_the_camera_simulator_imports_no_calibration():
    """The camera simulator's optics are its own (a lens polynomial in the field angle, a tilted detector), never
    OpenCV's model that calibration/camera fits: it takes nothing of calibration/."""
    paths = [ROOT / "drivers" / "sim" / "camera.py", ROOT / "drivers" / "sim" / "camera_optics.py"]
    bad = [f"{_where(p)}:{line} imports {m}" for p in paths for m, line in _imported_modules(p)
           if m.split(".")[0] == "calibration"]
    assert not bad, "\n".join(bad)


def test_the_qd_simulator_imports_no_calibration():
    """A simulator is its own physics (DESIGN.md "Sensor families"): the QD simulator does not even take its
    defaults from calibration/, so nothing of the fit can leak into the currents it makes."""
    paths = sorted((ROOT / "drivers" / "sim").glob("qd_*.py"))
    assert ROOT / "drivers" / "sim" / "qd_sensor.py" in paths, "drivers/sim/qd_sensor.py is missing"
    bad = [f"{_where(p)}:{line} imports {m}" for p in paths for m, line in _imported_modules(p)
           if m.split(".")[0] == "calibration"]
    assert not bad, "\n".join(bad)


def test_the_css_simulator_imports_no_calibration():
    """The CSS head's simulator and its physics (drivers/sim/css_*.py) are their own: calibration/css fits what
    they make, so they take nothing of calibration/ (not even the channel names: css_optics knows its own)."""
    paths = sorted((ROOT / "drivers" / "sim").glob("css_*.py"))
    assert ROOT / "drivers" / "sim" / "css_head.py" in paths, "drivers/sim/css_head.py is missing"
    bad = [f"{_where(p)}:{line} imports {m}" for p in paths for m, line in _imported_modules(p)
           if m.split(".")[0] == "calibration"]
    assert not bad, "\n".join(bad)


def test_the_horizon_simulator_imports_no_calibration():
    """The horizon sensor's simulator, its physics and the Earth simulator (drivers/sim/horizon_*.py,
    earth_simulator.py) are their own: calibration/horizon fits what they make, so they take nothing of calibration/
    (not the cone geometry of calibration/horizon/scan.py, not its constants)."""
    paths = sorted((ROOT / "drivers" / "sim").glob("horizon_*.py")) + [ROOT / "drivers" / "sim" / "earth_simulator.py"]
    assert ROOT / "drivers" / "sim" / "horizon_sensor.py" in paths, "drivers/sim/horizon_sensor.py is missing"
    bad = [f"{_where(p)}:{line} imports {m}" for p in paths for m, line in _imported_modules(p)
           if m.split(".")[0] == "calibration"]
    assert not bad, "\n".join(bad)


def test_the_import_reader_resolves_relative_and_nested_imports(tmp_path):
    pkg = tmp_path / "top" / "sub"
    pkg.mkdir(parents=True)
    (tmp_path / "top" / "design.py").write_text("")
    (pkg / "sibling.py").write_text("")
    probe = pkg / "probe.py"
    probe.write_text("from .. import design\nfrom ..other import thing\nfrom . import sibling, CONSTANT\n"
                     "import numpy.linalg\n"
                     "def f():\n    from ...elsewhere import x\n")
    with pytest.raises(AssertionError, match="climbs above"):
        _imported_modules(probe, tmp_path)
    probe.write_text(probe.read_text().replace("...elsewhere", ".deep.er"))
    assert sorted(_imported_modules(probe, tmp_path)) == [
        ("numpy.linalg", 4), ("top.design", 1), ("top.other", 2), ("top.sub", 3), ("top.sub.deep.er", 6),
        ("top.sub.sibling", 3)]
    assert _imports(probe, tmp_path) == {"numpy", "top"}


# --------------------------------------------------------------------------------------------------------
# The rules this file held first
# --------------------------------------------------------------------------------------------------------

def test_calibration_imports_nothing_else_of_the_project():
    for path in (ROOT / "calibration").rglob("*.py"):
        assert not _imports(path) & {"bench", "cli", "drivers", "web"}, path


def test_bench_imports_neither_web_nor_the_command_line():
    """The web layer sits on the bench, never under it; the `cli/` package composes both."""
    for path in (ROOT / "bench").rglob("*.py"):
        assert not _imports(path) & {"web", "cli"}, path


def test_only_the_entry_point_imports_the_command_line():
    """`cli/` is the composition root: pyproject's console script is its way in, and no module of the project
    imports it (the tests reach the composed app through tests/clitools.py alone)."""
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert pyproject["project"]["scripts"]["sunbench"] == "cli.main:app"
    assert "cli*" in pyproject["tool"]["setuptools"]["packages"]["find"]["include"]
    importers = {path.relative_to(ROOT).as_posix()
                 for folder in ("bench", "calibration", "drivers", "web", "tests", "scripts")
                 for path in (ROOT / folder).rglob("*.py") if "cli" in _imports(path)}
    assert importers == {"tests/clitools.py"}


def test_the_import_checks_see_imports_inside_functions(tmp_path):
    # `serve` imports the web app when it runs; such an import in bench/ must not slip past the checks
    path = tmp_path / "probe.py"
    path.write_text("def f():\n    from web.app import create_app\n    import importlib\n"
                    "    importlib.import_module('cli.main')\n")
    assert _imports(path) == {"web", "importlib", "cli"}


def test_calibration_does_no_io():
    forbidden = {"open", "print", "input"}
    for path in (ROOT / "calibration").rglob("*.py"):
        tree = ast.parse(path.read_text())
        calls = {n.func.id for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
        assert not calls & forbidden, (path, calls & forbidden)
        assert not _imports(path) & {"os", "pathlib", "io", "json", "csv", "sqlite3", "serial"}, path


def test_every_public_calibration_function_cites_its_source():
    """Public functions of the numerical modules carry a docstring that names a seed or the research note."""
    for name in ("geometry", "pinhole", "models/seed003", "synthetic"):
        tree = ast.parse((ROOT / "calibration" / f"{name}.py").read_text())
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
                doc = ast.get_docstring(node) or ""
                if node.name in {"wrap_deg", "sector_of", "spot_from_vectors"}:
                    assert doc, node.name  # helpers: a docstring, the citation sits with their callers
                    continue
                assert "seed 0" in doc or "research note" in doc, f"{name}.{node.name} cites no source"


# --------------------------------------------------------------------------------------------------------
# 2. Every driver that talks a wire protocol has a simulator that serves it and a byte-level test
# --------------------------------------------------------------------------------------------------------

#: Modules of drivers/ that are not a device's driver over a wire protocol of ours (besides *_protocol.py,
#: the framing a driver and its simulator share).
NOT_WIRE_DRIVERS = {
    "__init__.py": "the package",
    "interfaces.py": "the abstract device interfaces the bench talks to",
    "errors.py": "the drivers' exceptions",
    "transport.py": "the port itself (serial_for_url): what every driver talks through",
    "testing.py": "the scripted port the byte-level tests use",
    "manual.py": "an operator sets the angle and confirms it: no wire",
    "usb_camera.py": "a camera through OpenCV's VideoCapture (webcam, video file, image sequence): OpenCV owns "
                     "the wire, no protocol of ours to simulate or script",
    "sources.py": "composes the supply and shutter drivers into sun simulators; it talks to no port itself, its "
                  "parts do (Oriel69907, ScpiSupply, ThorlabsSC10 below)",
}


@dataclass(frozen=True)
class WireDriver:
    simulator: str  # the module under drivers/sim/ that serves the driver's protocol
    simulator_class: str
    byte_test: str  # the test under tests/drivers/ that scripts (sent, reply) exchanges against the driver


#: "drivers/<module>.py:<class>" -> its simulator and its byte-level test. A driver class that takes a port and
#: has no row here fails `test_every_wire_driver_is_in_the_table`.
WIRE_DRIVERS = {
    "drivers/cmos_sensor.py:CmosSunSensor":
        WireDriver("drivers/sim/cmos_sensor.py", "CmosSensorSimulator", "tests/drivers/test_cmos_sensor.py"),
    "drivers/css_sensor.py:CssHead":
        WireDriver("drivers/sim/css_head.py", "CssHeadSimulator", "tests/drivers/test_css_sensor.py"),
    "drivers/earth_simulator.py:EarthSimulatorSource":
        WireDriver("drivers/sim/earth_simulator.py", "EarthSimulatorSimulator",
                   "tests/drivers/test_earth_simulator.py"),
    "drivers/horizon_sensor.py:HorizonSensorModule":
        WireDriver("drivers/sim/horizon_sensor.py", "HorizonSensorSimulator", "tests/drivers/test_horizon_sensor.py"),
    "drivers/meade.py:LX200Table":
        WireDriver("drivers/sim/lx200.py", "LX200Simulator", "tests/drivers/test_meade.py"),
    "drivers/newport_smc100.py:Smc100Axis":
        WireDriver("drivers/sim/newport_smc100.py", "Smc100Simulator", "tests/drivers/test_newport_smc100.py"),
    "drivers/oriel69907.py:Oriel69907":
        WireDriver("drivers/sim/oriel69907.py", "Oriel69907Simulator", "tests/drivers/test_oriel69907.py"),
    "drivers/qd_sensor.py:QdSunSensor":
        WireDriver("drivers/sim/qd_sensor.py", "QdSensorSimulator", "tests/drivers/test_qd_sensor.py"),
    "drivers/scpi_supply.py:ScpiSupply":
        WireDriver("drivers/sim/scpi_supply.py", "ScpiSupplySimulator", "tests/drivers/test_scpi_supply.py"),
    "drivers/shutter.py:ThorlabsSC10":
        WireDriver("drivers/sim/shutter.py", "ThorlabsSC10Simulator", "tests/drivers/test_shutter.py"),
    "drivers/thorlabs_apt.py:AptRotationStage":
        WireDriver("drivers/sim/thorlabs_apt.py", "AptStageSimulator", "tests/drivers/test_thorlabs_apt.py"),
}


def _takes_a_port(cls: ast.ClassDef) -> bool:
    """A class whose constructor takes a `port` or `transport` (by name, or annotated `Port`)."""
    for node in cls.body:
        if isinstance(node, ast.FunctionDef) and node.name == "__init__":
            a = node.args
            for arg in a.posonlyargs + a.args + a.kwonlyargs:
                ann = arg.annotation
                ann_name = getattr(ann, "id", None) or getattr(ann, "attr", None) or getattr(ann, "value", None)
                if arg.arg in ("port", "transport") or ann_name == "Port":
                    return True
    return False


def _port_classes(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    return [n.name for n in tree.body if isinstance(n, ast.ClassDef) and _takes_a_port(n)]


def _is_protocol_module(path: Path) -> bool:
    return path.name.endswith("_protocol.py")


def _wire_drivers_found() -> set[str]:
    return {f"{_where(p)}:{cls}" for p in sorted((ROOT / "drivers").glob("*.py"))
            if p.name not in NOT_WIRE_DRIVERS and not _is_protocol_module(p) for cls in _port_classes(p)}


def test_every_wire_driver_is_in_the_table():
    found = _wire_drivers_found()
    missing = sorted(found - set(WIRE_DRIVERS))
    stale = sorted(set(WIRE_DRIVERS) - found)
    assert not missing, ("driver classes that take a port but have no row in WIRE_DRIVERS (their simulator "
                         "and byte-level test): " + ", ".join(missing))
    assert not stale, "WIRE_DRIVERS rows whose driver class takes no port or is gone: " + ", ".join(stale)


def test_every_drivers_module_is_a_wire_driver_or_says_why_not():
    """Each module of drivers/ is a driver in WIRE_DRIVERS, a protocol's framing, or named in NOT_WIRE_DRIVERS
    with its reason; and nothing excluded hides a class that takes a port."""
    drivers_in_table = {key.split(":")[0] for key in WIRE_DRIVERS}
    for path in sorted((ROOT / "drivers").glob("*.py")):
        where = _where(path)
        if path.name in NOT_WIRE_DRIVERS or _is_protocol_module(path):
            assert not _port_classes(path), (f"{where} is excluded as no wire driver, yet "
                                             f"{', '.join(_port_classes(path))} takes a port")
        else:
            assert where in drivers_in_table, (
                f"{where} has no class that takes a port/transport and is not in NOT_WIRE_DRIVERS: a driver "
                f"takes an open transport (DESIGN.md), or name the module in NOT_WIRE_DRIVERS with the reason")


@pytest.mark.parametrize("driver", sorted(WIRE_DRIVERS))
def test_every_wire_driver_has_a_simulator_that_serves_its_protocol(driver):
    from drivers.sim.device import LineDevice, SimDevice

    entry = WIRE_DRIVERS[driver]
    path = ROOT / entry.simulator
    assert path.is_file() and path.parent == ROOT / "drivers" / "sim", (
        f"{driver}: its simulator {entry.simulator} is missing (a simulator lives in drivers/sim/)")
    tree = ast.parse(path.read_text())
    assert entry.simulator_class in {n.name for n in tree.body if isinstance(n, ast.ClassDef)}, (
        f"{driver}: {entry.simulator} defines no class {entry.simulator_class}")
    module = importlib.import_module(entry.simulator.removesuffix(".py").replace("/", "."))
    sim = getattr(module, entry.simulator_class)
    # a protocol front: bytes in, bytes out, through the ``sim://`` port and the TCP server
    assert issubclass(sim, SimDevice), f"{entry.simulator}:{entry.simulator_class} is no drivers.sim.device.SimDevice"
    assert sim.handle is not SimDevice.handle, f"{entry.simulator}:{entry.simulator_class} handles no bytes"
    if issubclass(sim, LineDevice):
        assert sim.handle_line is not LineDevice.handle_line, (
            f"{entry.simulator}:{entry.simulator_class} handles no lines")


def _callers_of(tree: ast.Module, name: str) -> set[str]:
    """`name` and the module's functions that call it, directly or through one another."""
    names = {name}
    functions = [n for n in tree.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]
    while True:
        more = {f.name for f in functions if f.name not in names and any(
            isinstance(c, ast.Call) and isinstance(c.func, ast.Name) and c.func.id in names for c in ast.walk(f))}
        if not more:
            return names
        names |= more


@pytest.mark.parametrize("driver", sorted(WIRE_DRIVERS))
def test_every_wire_driver_has_a_byte_level_test(driver):
    """PyMeasure style: a test under tests/drivers/ builds the driver class on `drivers.testing.scripted_port`
    and so checks the exact bytes it sends against scripted (sent, reply) exchanges."""
    module_path, cls = driver.split(":")
    driver_module = module_path.removesuffix(".py").replace("/", ".")
    entry = WIRE_DRIVERS[driver]
    path = ROOT / entry.byte_test
    assert path.is_file() and path.parent == ROOT / "tests" / "drivers", (
        f"{driver}: its byte-level test {entry.byte_test} is missing (it lives in tests/drivers/)")
    tree = ast.parse(path.read_text())
    local = {}  # a name in the test -> the dotted name it was imported as
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0:
            for a in node.names:
                local[a.asname or a.name] = f"{node.module}.{a.name}"
    port_names = {n for n, full in local.items() if full == "drivers.testing.scripted_port"}
    cls_names = {n for n, full in local.items() if full == f"{driver_module}.{cls}"}
    assert port_names, f"{entry.byte_test} does not import scripted_port from drivers.testing"
    assert cls_names, f"{entry.byte_test} does not import {cls} from {driver_module}"
    builders = set().union(*(_callers_of(tree, n) for n in cls_names))
    scripted = 0
    for node in ast.walk(tree):
        if not isinstance(node, (ast.With, ast.AsyncWith)):
            continue
        ports = {item.optional_vars.id for item in node.items
                 if isinstance(item.context_expr, ast.Call) and isinstance(item.context_expr.func, ast.Name)
                 and item.context_expr.func.id in port_names and isinstance(item.optional_vars, ast.Name)}
        if ports and any(isinstance(c, ast.Call) and isinstance(c.func, ast.Name) and c.func.id in builders
                         and any(isinstance(a, ast.Name) and a.id in ports
                                 for a in list(c.args) + [k.value for k in c.keywords])
                         for stmt in node.body for c in ast.walk(stmt)):
            scripted += 1
    assert scripted, (f"{entry.byte_test} never builds {cls} on a scripted_port "
                      f"(`with scripted_port([...]) as port: {cls}(port, ...)`, or through a helper)")


# --------------------------------------------------------------------------------------------------------
# 3. Every registered sensor family has its shape in every layer (DESIGN.md "Sensor families")
# --------------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FamilyParts:
    calibration: str  # its calibration package (a folder) or module under calibration/
    simulator: str  # its sensor's simulator under drivers/sim/ (a WIRE_DRIVERS simulator)


FAMILY_PARTS = {
    "cmos": FamilyParts("calibration/models", "drivers/sim/cmos_sensor.py"),
    "qd": FamilyParts("calibration/qd", "drivers/sim/qd_sensor.py"),
    "camera": FamilyParts("calibration/camera", "drivers/sim/camera.py"),
    "css": FamilyParts("calibration/css", "drivers/sim/css_head.py"),
    "horizon": FamilyParts("calibration/horizon", "drivers/sim/horizon_sensor.py"),
}

#: Families whose simulator is not a WIRE_DRIVERS simulator, each named with the reason it stands (the rule holds
#: for every other family). A listed family whose simulator became one fails
#: `test_every_family_simulator_exception_is_still_needed`.
FAMILY_SIMULATOR_EXCEPTIONS = {
    "camera":
        # A USB camera's wire is UVC, spoken by the kernel's V4L2 driver and read by OpenCV's VideoCapture
        # (NOT_WIRE_DRIVERS: usb_camera.py); no protocol of ours runs on it, and a user-space simulator cannot sit
        # on it without the v4l2loopback kernel module (a fake /dev/videoN). So the simulated camera is an
        # in-process ImageSensor handed to the bench directly (bench/hardware.py), and the real driver is tested
        # on its frames through an image sequence instead (tests/drivers/test_sim_camera.py).
        "the camera's wire is UVC in the kernel (OpenCV owns it): the simulator is an in-process ImageSensor",
}


def test_every_registered_family_has_a_descriptor_a_calibration_and_a_simulator():
    """Iterates what bench.families registers (a family not registered yet is simply not checked)."""
    from bench.descriptor import ReadingDescriptor
    from bench.families import families

    registered = families()
    assert registered, "bench.families registers no family"
    simulators = {w.simulator for w in WIRE_DRIVERS.values()}
    for name, family in sorted(registered.items()):
        module = getattr(family.read, "__module__", "bench.families")
        assert name in FAMILY_PARTS, f"family {name!r} ({module}) has no row in FAMILY_PARTS"
        parts = FAMILY_PARTS[name]
        assert isinstance(family.descriptor, ReadingDescriptor), (
            f"family {name!r} ({module}): its descriptor is a {type(family.descriptor).__name__}")
        assert family.descriptor.family == name, (
            f"family {name!r} ({module}) describes a reading of family {family.descriptor.family!r}")
        target = ROOT / parts.calibration
        dotted = parts.calibration.removesuffix(".py").replace("/", ".")
        assert parts.calibration.startswith("calibration/") and (
            (target.is_dir() and any(target.glob("*.py"))) or target.with_suffix(".py").is_file()), (
            f"family {name!r}: its calibration {parts.calibration} is missing")
        assert importlib.util.find_spec(dotted) is not None, f"family {name!r}: {dotted} is not importable"
        assert (ROOT / parts.simulator).is_file(), f"family {name!r}: its simulator {parts.simulator} is missing"
        if name in FAMILY_SIMULATOR_EXCEPTIONS:
            continue  # named with its reason; checked below
        assert parts.simulator in simulators, (
            f"family {name!r}: {parts.simulator} serves no driver in WIRE_DRIVERS (a simulator speaks its "
            f"sensor's wire protocol)")


def test_every_family_simulator_exception_is_still_needed():
    """A family excepted from the wire-simulator rule has a row, a simulator that is indeed no WIRE_DRIVERS one,
    and the simulator implements its sensor's driver interface in-process (an ImageSensor)."""
    from drivers.interfaces import ImageSensor, QuadrantSensor

    simulators = {w.simulator for w in WIRE_DRIVERS.values()}
    for name, reason in FAMILY_SIMULATOR_EXCEPTIONS.items():
        assert name in FAMILY_PARTS, f"FAMILY_SIMULATOR_EXCEPTIONS names {name!r}, which has no FAMILY_PARTS row"
        simulator = FAMILY_PARTS[name].simulator
        assert simulator not in simulators, (f"{simulator} is a WIRE_DRIVERS simulator now: drop {name!r} from "
                                             f"FAMILY_SIMULATOR_EXCEPTIONS ({reason})")
        module = importlib.import_module(simulator.removesuffix(".py").replace("/", "."))
        interfaces = [c for c in vars(module).values() if isinstance(c, type) and c.__module__ == module.__name__
                      and issubclass(c, (ImageSensor, QuadrantSensor))]
        assert interfaces, f"{simulator} implements no sensor interface (drivers.interfaces) in-process"


def _assert_tool_finds_nothing(tool: str, *args: str, timeout: float) -> None:
    """The venv's `tool ARGS`, run at the project's root, exits 0 (its findings otherwise)."""
    import subprocess

    exe = Path(sys.executable).with_name(tool)
    assert exe.exists(), f"no {exe}: install the test extras (bash scripts/setup.sh)"
    result = subprocess.run([str(exe), *args], cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]


def test_ruff_finds_nothing():
    """The lint the project configures (pyproject.toml [tool.ruff]) is clean; ruff comes with the test extras."""
    _assert_tool_finds_nothing("ruff", "check", "--no-cache", "--output-format", "concise", ".", timeout=120)


def test_mypy_finds_nothing_in_the_typed_seams():
    """mypy checks the modules pyproject.toml [tool.mypy] lists (the seams every family goes through)."""
    _assert_tool_finds_nothing("mypy", "--no-incremental", timeout=300)
