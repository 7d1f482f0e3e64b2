"""Protocol front of the simulated SCPI bench supply that drives the LED sun simulator
(anchors-protocols §4.2; the sunbench driver is :mod:`drivers.scpi_supply`).

Device analysis (lewis style: the protocol first, then the state):

**Framing.** A program message ends with LF (a CR before it is ignored); its response message — every
query's answer in the message, joined by ``;`` — ends with `out_terminator` (LF by default). A message with
no query answers nothing.

**Parsing (SCPI-99 vol. 1 §6, IEEE 488.2 §7).**

* Message units are separated by ``;`` (outside quoted strings). A header that starts with ``:`` starts
  from the root; one that does not is taken relative to the *current path*: the nodes of the previous
  compound header of the same message, less its last one (``SOUR:VOLT 5;CURR 1`` is ``SOUR:CURR 1``,
  ``INST:NSEL 1;VOLT 5`` is the undefined ``INST:VOLT``, hence pymeasure's ``INST:NSEL 1;:VOLT 5``). Common
  commands (``*XXX``) leave the path alone; every message starts at the root.
* Mnemonics are case-insensitive and take the short or the long form (``OUTP``/``OUTPut``); nodes in
  brackets are optional: ``[SOURce:]VOLTage[:LEVel][:IMMediate][:AMPLitude]``, ``OUTPut[:STATe]``,
  ``MEASure[:SCALar]:CURRent[:DC]?``, ``SYSTem:ERRor[:NEXT]?``, ``INSTrument[:SELect]``.
* Parameters follow the header after white space, separated by commas: numbers (NRf, with an optional
  unit ``V``/``MV``/``A``/``MA``, or ``MIN``/``MAX``/``DEF``), booleans (``ON``/``OFF``/``1``/``0``), output
  names and channel lists (``(@1)``, ``(@1,2)``, ``(@1:3)``).

**Commands.**

* IEEE 488.2 common commands: ``*IDN? *RST *CLS *OPC *OPC? *ESR? *ESE <n> *ESE? *SRE <n> *SRE? *STB?
  *WAI *OPT? *TST?``.
* ``SYSTem:ERRor[:NEXT]?``, ``SYSTem:ERRor:COUNt?``, ``SYSTem:VERSion?`` (``1999.0``), ``SYSTem:REMote``,
  ``SYSTem:LOCal``, ``SYSTem:RWLock``.
* ``INSTrument[:SELect] P6V|P25V|N25V|CH<n>`` / ``?``, ``INSTrument:NSELect 1|2|3`` / ``?``: the output the
  setpoint commands address.
* ``[SOURce:]VOLTage[...] <V>|MIN|MAX|DEF`` / ``VOLTage? [MIN|MAX]``, the same for ``CURRent``.
* ``APPLy [<output>,]<V>|DEF|MIN|MAX[,<A>|DEF|MIN|MAX]`` (without the output name: the selected output) /
  ``APPLy? [<output>]`` → ``"<V>,<A>"``.
* ``OUTPut[:STATe] ON|OFF[,(@<list>)]`` / ``OUTPut[:STATe]? [(@<list>)]``: without a list every output
  switches (the E3631A's outputs switch together) and the query reads the selected output; with a list
  (the E36300-series form pymeasure sends, ``OUTPut 1, (@1)``) only the listed outputs.
* ``OUTPut:TRACk[:STATe] ON|OFF`` / ``?``: the negative output tracks the positive 25 V output.
* ``MEASure[:SCALar]:VOLTage[:DC]? [<output>|(@n)]``, ``MEASure[:SCALar]:CURRent[:DC]? [...]``.

**Errors are never silent.** Each goes on the error queue (``SYST:ERR?`` pops the oldest as
``<code>,"<text>"``, ``0,"No error"`` when empty; with `queue_size` entries queued the last is replaced by
``-350,"Queue overflow"`` and later ones are lost; ``*CLS`` empties it) and sets its event-status bit: a
command error (−100 … −199: −102 syntax, −104 data type, −108 parameter not allowed, −109 missing
parameter, −113 undefined header, −131 invalid suffix) bit 5 CME, an execution error (−221 settings
conflict, −222 data out of range, −224 illegal parameter value) bit 4 EXE, a device-dependent error bit 3
DDE, a query error bit 2 QYE. The status byte: bit 2 error queue not empty, bit 4 MAV (an answer of an
earlier query of the same message is pending), bit 5 ESB (ESR & ESE), bit 6 MSS (STB & SRE). The query
errors −410/−420 (a query interrupted or unterminated) cannot happen here: an answer is on the wire as soon
as its message ends.

**State.** Three outputs laid out as an Agilent/Keysight E3631A (the RTS2 and pymeasure clients' model):
``P6V`` 0 … 6.18 V, 0 … 5.15 A; ``P25V`` 0 … 25.75 V, 0 … 1.03 A; ``N25V`` 0 … −25.75 V, 0 … 1.03 A
(:data:`E3631A_OUTPUTS`; pass `outputs` for another supply). ``*RST`` (as on the E3631A): outputs off,
0 V, current limits at full scale, output 1 selected, tracking off; the error queue and the status
enables are kept (IEEE 488.2). At power-on output 1 holds 5 V and 0 A (a bench supply left that way), so
the LED driver may send the current alone.

**The LED.** Output `led_output` (1) drives the world's LED string (2.9 V + 1 V/A): switching it on starts
the lamp model (``LampModel.start``) and opens its "shutter" (the LED shines), off stops and closes it.
Constant current while the voltage setpoint exceeds the string's forward voltage, else constant voltage at
the current the setpoint allows; ``MEAS:CURR?`` and the lamp model get that current. A failed LED
(``lamp.inject_fault()``) is an open string: no current, the voltage at its setpoint. The other outputs
are unloaded (0 A, their setpoint when on). ``OUTP ON`` while the lamp's interlock is open (a remote-inhibit
input wired to the bench interlock) is refused with −221 and leaves the outputs off.

In instant mode (clock time scale 0) asking ``OUTP?`` of the LED output while it is on completes the LED's
warm-up, as observing an axis completes its move.

Back door: the WireFaults of every simulator, ``world.lamp.inject_fault()`` / ``.interlock_open``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from .device import LineDevice
from .world import SimWorld

IDENTITY = "SUNBENCH,SCPI-SUPPLY-SIM,0,1.0"
SCPI_VERSION = "1999.0"
LED_FORWARD_V = 2.9  # forward voltage of the LED string at 0 A [V]
LED_SLOPE_V_PER_A = 1.0  # its dynamic resistance [V/A]

ERRORS = {
    -100: "Command error", -102: "Syntax error", -104: "Data type error", -108: "Parameter not allowed",
    -109: "Missing parameter", -113: "Undefined header", -131: "Invalid suffix", -200: "Execution error",
    -221: "Settings conflict", -222: "Data out of range", -224: "Illegal parameter value",
    -350: "Queue overflow",
}

# IEEE 488.2 event status register and status byte
ESR_OPC, ESR_QYE, ESR_DDE, ESR_EXE, ESR_CME, ESR_URQ, ESR_PON = 0x01, 0x04, 0x08, 0x10, 0x20, 0x40, 0x80
STB_EAV, STB_MAV, STB_ESB, STB_MSS = 0x04, 0x10, 0x20, 0x40


@dataclass(frozen=True)
class OutputSpec:
    """One output of the supply: its name and programming ranges (``limit_v`` is negative for a negative
    output)."""

    name: str
    limit_v: float
    max_current_a: float

    @property
    def voltage_range(self) -> tuple[float, float]:
        return (min(0.0, self.limit_v), max(0.0, self.limit_v))


# Agilent/Keysight E3631A programming ranges (its user's guide, "Specifications"; 3 % over the rating)
E3631A_OUTPUTS = (OutputSpec("P6V", 6.18, 5.15), OutputSpec("P25V", 25.75, 1.03), OutputSpec("N25V", -25.75, 1.03))


class _Error(Exception):
    def __init__(self, code: int):
        super().__init__(code)
        self.code = code


@dataclass(frozen=True)
class _Node:
    short: str
    long: str
    optional: bool


def _pattern(text: str) -> tuple[_Node, ...]:
    """``"[SOURce:]VOLTage[:LEVel]"`` → its nodes: the short form is the upper-case part of the mnemonic."""
    nodes = []
    for optional, name in re.findall(r"(\[?):?([A-Za-z]+):?\]?", text):
        nodes.append(_Node("".join(c for c in name if c.isupper()), name.upper(), bool(optional)))
    return tuple(nodes)


def _matches(nodes: tuple[_Node, ...], words: list[str]) -> bool:
    if not nodes:
        return not words
    node = nodes[0]
    if words and words[0] in (node.short, node.long) and _matches(nodes[1:], words[1:]):
        return True
    return node.optional and _matches(nodes[1:], words)


def _split(text: str, separator: str) -> list[str]:
    """Split on `separator` outside double/single quotes and parentheses; -102 on an unbalanced one."""
    parts, current, quote, depth = [], [], "", 0
    for char in text:
        if quote:
            if char == quote:
                quote = ""
        elif char in "\"'":
            quote = char
        elif char == "(":
            depth += 1
        elif char == ")":
            depth -= 1
            if depth < 0:
                raise _Error(-102)
        elif char == separator and depth == 0:
            parts.append("".join(current))
            current = []
            continue
        current.append(char)
    if quote or depth:
        raise _Error(-102)
    parts.append("".join(current))
    return parts


_NUMBER = re.compile(r"^([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z]*)$")
_MNEMONIC = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_KEYWORDS = {"MIN": "MIN", "MINIMUM": "MIN", "MAX": "MAX", "MAXIMUM": "MAX", "DEF": "DEF", "DEFAULT": "DEF"}


class ScpiSupplySimulator(LineDevice):
    """The bench supply of the simulated LED sun simulator; output `led_output` drives ``world.lamp``.

    Parameters
    ----------
    world : SimWorld
    out_terminator : bytes
        End of every response message (LF; ``b"\\r\\n"`` for a supply that answers CR LF).
    queue_size : int
        Entries the error queue holds, the last of them becoming −350 on overflow.
    outputs : sequence of OutputSpec
        The outputs, numbered from 1 (:data:`E3631A_OUTPUTS`).
    led_output : int
        Number of the output wired to the LED string.
    """

    name = "scpi-supply"
    in_terminator = b"\n"

    def __init__(self, world: SimWorld, *, out_terminator: bytes = b"\n", queue_size: int = 20,
                 outputs: tuple[OutputSpec, ...] = E3631A_OUTPUTS, led_output: int = 1):
        super().__init__()
        if not 1 <= led_output <= len(outputs):
            raise ValueError(f"led_output {led_output} is not one of the {len(outputs)} outputs")
        self.world = world
        self.lamp = world.lamp
        self.out_terminator = out_terminator
        self.queue_size = queue_size
        self.specs = tuple(outputs)
        self.led = led_output - 1
        self.errors: list[int] = []
        self.esr = ESR_PON  # the power-on bit, as after switching the supply on
        self.ese = 0
        self.sre = 0
        self.remote = False
        self.commands = 0  # program messages handled, for tests that check nothing reached the supply
        self._reset()
        self.voltages[self.led], self.currents[self.led] = 5.0, 0.0  # power-on: see the module docstring
        self._commands = [(_pattern(text), set_, query) for text, set_, query in (
            ("[SOURce:]VOLTage[:LEVel][:IMMediate][:AMPLitude]", self._set_voltage, self._query_voltage),
            ("[SOURce:]CURRent[:LEVel][:IMMediate][:AMPLitude]", self._set_current, self._query_current),
            ("APPLy", self._apply, self._query_apply),
            ("OUTPut[:STATe]", self._set_output_state, self._query_output_state),
            ("OUTPut:TRACk[:STATe]", self._set_tracking, self._query_tracking),
            ("MEASure[:SCALar]:VOLTage[:DC]", None, self._measure_voltage),
            ("MEASure[:SCALar]:CURRent[:DC]", None, self._measure_current),
            ("INSTrument[:SELect]", self._select, self._query_select),
            ("INSTrument:NSELect", self._nselect, self._query_nselect),
            ("SYSTem:ERRor[:NEXT]", None, self._next_error),
            ("SYSTem:ERRor:COUNt", None, lambda params: self._no_params(params) or str(len(self.errors))),
            ("SYSTem:VERSion", None, lambda params: self._no_params(params) or SCPI_VERSION),
            ("SYSTem:REMote", lambda params: self._set_remote(params, True), None),
            ("SYSTem:RWLock", lambda params: self._set_remote(params, True), None),
            ("SYSTem:LOCal", lambda params: self._set_remote(params, False), None),
        )]

    # -- state -----------------------------------------------------------------------------------------
    def _reset(self) -> None:
        """The ``*RST`` state (E3631A): outputs off, 0 V, full-scale current limits, output 1 selected."""
        self.voltages = [0.0] * len(self.specs)
        self.currents = [spec.max_current_a for spec in self.specs]
        self.states = [False] * len(self.specs)
        self.selected = 0
        self.tracking = False
        self._drive_led()

    # compatibility views of the LED output
    @property
    def output(self) -> bool:
        """Whether the LED output is on."""
        return self.states[self.led]

    @property
    def current_a(self) -> float:
        """Current setpoint of the LED output [A]."""
        return self.currents[self.led]

    @property
    def voltage_v(self) -> float:
        """Voltage setpoint of the LED output [V]."""
        return self.voltages[self.led]

    def _error(self, code: int) -> None:
        """Queue an error and set its event-status bit: never silent."""
        if len(self.errors) < self.queue_size:
            self.errors.append(code)
        else:
            self.errors[-1] = -350
        if -199 <= code <= -100:
            self.esr |= ESR_CME
        elif -299 <= code <= -200:
            self.esr |= ESR_EXE
        elif -399 <= code <= -300 and code != -350:
            self.esr |= ESR_DDE
        elif -499 <= code <= -400:
            self.esr |= ESR_QYE

    def _led_current(self) -> float:
        """The current the LED string draws [A]: constant current above its forward voltage, else what the
        voltage setpoint allows; none when off, failed or not lit."""
        i = self.led
        if not (self.states[i] and self.lamp.on and not self.lamp.fault):
            return 0.0
        allowed = max((self.voltages[i] - LED_FORWARD_V) / LED_SLOPE_V_PER_A, 0.0)
        return min(self.currents[i], allowed)

    def _drive_led(self) -> None:
        """Bring the lamp model in line with the LED output."""
        on = self.states[self.led]
        if on:
            self.lamp.start()
            self.lamp.current_a = self._led_current()
        else:
            self.lamp.stop()
        self.lamp.shutter_open = on

    def _measured(self, index: int) -> tuple[float, float]:
        """(voltage [V], current [A]) at output `index`."""
        if not self.states[index]:
            return 0.0, 0.0
        if index != self.led:
            return self.voltages[index], 0.0
        current = self._led_current()
        if current == 0.0:
            return self.voltages[index], 0.0  # open (or unlit) string: the supply sits at its setpoint
        return min(LED_FORWARD_V + LED_SLOPE_V_PER_A * current, self.voltages[index]), current

    def stb(self, *, pending: bool = False) -> int:
        value = (STB_EAV if self.errors else 0) | (STB_MAV if pending else 0)
        if self.esr & self.ese:
            value |= STB_ESB
        if value & self.sre & ~STB_MSS:
            value |= STB_MSS
        return value

    # -- protocol --------------------------------------------------------------------------------------
    def handle_line(self, line: bytes) -> bytes:
        self.commands += 1
        text = line.decode("ascii", errors="replace").strip()
        if not text:
            return b""
        answers = self._message(text)
        return ";".join(answers).encode("ascii") + self.out_terminator if answers else b""

    def _message(self, text: str) -> list[str]:
        """Execute one program message; returns the answers of its queries."""
        try:
            units = _split(text, ";")
        except _Error as exc:
            self._error(exc.code)
            return []
        answers: list[str] = []
        path: list[str] = []
        for unit in units:
            unit = unit.strip()
            if not unit:
                continue
            try:
                answer, path = self._unit(unit, path, pending=bool(answers))
            except _Error as exc:
                self._error(exc.code)
                continue
            if answer is not None:
                answers.append(answer)
        return answers

    def _unit(self, unit: str, path: list[str], *, pending: bool) -> tuple[str | None, list[str]]:
        """Execute one message unit; returns its answer (None for a command) and the new current path."""
        header, _, rest = unit.replace("\t", " ").partition(" ")
        rest = rest.strip()
        params = [p.strip() for p in _split(rest, ",")] if rest else []
        if any(p == "" for p in params):
            raise _Error(-102)
        query = header.endswith("?")
        name = header[:-1] if query else header
        if name.startswith("*"):
            return self._common(name[1:].upper(), query, params, pending), path
        absolute = name.startswith(":")
        words = name[1:].split(":") if absolute else name.split(":")
        if not all(_MNEMONIC.match(word) for word in words):
            raise _Error(-102)
        words = [word.upper() for word in words]
        full = words if absolute else path + words
        new_path = full[:-1]
        for nodes, set_, ask in self._commands:
            if _matches(nodes, full):
                handler = ask if query else set_
                if handler is None:
                    raise _Error(-113)
                answer = handler(params)
                return (answer if query else None), new_path
        raise _Error(-113)

    # -- common commands (IEEE 488.2) -------------------------------------------------------------------
    def _common(self, name: str, query: bool, params: list[str], pending: bool) -> str | None:
        key = name + ("?" if query else "")
        if key in ("ESE", "SRE"):
            value = self._register_param(params)
            if key == "ESE":
                self.ese = value
            else:
                self.sre = value & ~STB_MSS
            return None
        if key not in ("IDN?", "RST", "CLS", "OPC", "OPC?", "ESR?", "ESE?", "SRE?", "STB?", "WAI", "OPT?", "TST?"):
            raise _Error(-113)
        self._no_params(params)
        if key == "IDN?":
            return IDENTITY
        if key == "RST":
            self._reset()
            return None
        if key == "CLS":
            self.errors.clear()
            self.esr = 0
            return None
        if key == "OPC":
            self.esr |= ESR_OPC  # every operation completes at once
            return None
        if key == "OPC?":
            return "1"
        if key == "ESR?":
            value, self.esr = self.esr, 0  # reading the register clears it
            return str(value)
        if key == "ESE?":
            return str(self.ese)
        if key == "SRE?":
            return str(self.sre)
        if key == "STB?":
            return str(self.stb(pending=pending))
        if key in ("OPT?", "TST?"):
            return "0"  # no options; the self-test passed
        return None  # *WAI: nothing is ever pending

    # -- parameters ------------------------------------------------------------------------------------
    @staticmethod
    def _no_params(params: list[str]) -> None:
        if params:
            raise _Error(-108)

    @staticmethod
    def _register_param(params: list[str]) -> int:
        if not params:
            raise _Error(-109)
        if len(params) > 1:
            raise _Error(-108)
        match = _NUMBER.match(params[0])
        if not match or match.group(2):
            raise _Error(-104)
        value = round(float(match.group(1)))
        if not 0 <= value <= 255:
            raise _Error(-222)
        return value

    @staticmethod
    def _number(text: str, unit: str, low: float, high: float, default: float) -> float:
        """A numeric parameter in `unit` (``V`` or ``A``, with an ``M`` milli prefix) or MIN/MAX/DEF."""
        keyword = _KEYWORDS.get(text.upper())
        if keyword:
            return {"MIN": low, "MAX": high, "DEF": default}[keyword]
        match = _NUMBER.match(text)
        if not match:
            raise _Error(-104)
        value, suffix = float(match.group(1)), match.group(2).upper()
        scale = {"": 1.0, unit: 1.0, "M" + unit: 1e-3, "U" + unit: 1e-6}.get(suffix)
        if scale is None:
            raise _Error(-131)
        value *= scale
        if not low - 1e-9 <= value <= high + 1e-9:
            raise _Error(-222)
        return value

    @staticmethod
    def _boolean(text: str) -> bool:
        word = text.upper()
        if word in ("ON", "OFF"):
            return word == "ON"
        match = _NUMBER.match(text)
        if match and not match.group(2):
            return round(float(match.group(1))) != 0
        if _MNEMONIC.match(text):
            raise _Error(-224)
        raise _Error(-104)

    def _output_index(self, text: str) -> int:
        """An output named by its name (``P6V``), ``CH<n>`` or a one-channel list ``(@n)``."""
        word = text.replace(" ", "").upper()
        for i, spec in enumerate(self.specs):
            if word in (spec.name.upper(), f"CH{i + 1}", f"OUT{i + 1}", f"OUTP{i + 1}"):
                return i
        channels = self._channel_list(text)
        if channels is not None:
            if len(channels) != 1:
                raise _Error(-108)
            return channels[0]
        if _MNEMONIC.match(word):
            raise _Error(-224)
        raise _Error(-104)

    def _channel_list(self, text: str) -> list[int] | None:
        """``(@1)``, ``(@1,3)``, ``(@1:3)`` → output indices; None when `text` is not a channel list."""
        text = text.replace(" ", "")
        if not (text.startswith("(@") and text.endswith(")")):
            return None
        indices = []
        for item in text[2:-1].split(","):
            first, _, last = item.partition(":")
            if not first.isdigit() or (last and not last.isdigit()):
                raise _Error(-102)
            for n in range(int(first), int(last or first) + 1):
                if not 1 <= n <= len(self.specs):
                    raise _Error(-222)
                indices.append(n - 1)
        return indices

    # -- setpoints -------------------------------------------------------------------------------------
    def _store_voltage(self, index: int, value: float) -> None:
        self.voltages[index] = value
        names = [spec.name for spec in self.specs]
        if self.tracking and "P25V" in names and "N25V" in names:
            p, n = names.index("P25V"), names.index("N25V")
            if index == p:
                self.voltages[n] = -value
            elif index == n:
                self.voltages[p] = -value
        self._drive_led()

    def _set_voltage(self, params: list[str]) -> None:
        if not params:
            raise _Error(-109)
        if len(params) > 1:
            raise _Error(-108)
        spec = self.specs[self.selected]
        low, high = spec.voltage_range
        self._store_voltage(self.selected, self._number(params[0], "V", low, high, 0.0))

    def _set_current(self, params: list[str]) -> None:
        if not params:
            raise _Error(-109)
        if len(params) > 1:
            raise _Error(-108)
        spec = self.specs[self.selected]
        self.currents[self.selected] = self._number(params[0], "A", 0.0, spec.max_current_a, spec.max_current_a)
        self._drive_led()

    def _limit_query(self, params: list[str], value: float, low: float, high: float) -> str:
        if len(params) > 1:
            raise _Error(-108)
        if params:
            keyword = _KEYWORDS.get(params[0].upper())
            if keyword not in ("MIN", "MAX"):
                raise _Error(-224 if _MNEMONIC.match(params[0]) else -104)
            value = low if keyword == "MIN" else high
        return f"{value:+.8E}"

    def _query_voltage(self, params: list[str]) -> str:
        low, high = self.specs[self.selected].voltage_range
        return self._limit_query(params, self.voltages[self.selected], low, high)

    def _query_current(self, params: list[str]) -> str:
        spec = self.specs[self.selected]
        return self._limit_query(params, self.currents[self.selected], 0.0, spec.max_current_a)

    def _apply(self, params: list[str]) -> None:
        if not params:
            raise _Error(-109)
        index = self.selected
        first = params[0].upper()
        if _KEYWORDS.get(first) is None and (_MNEMONIC.match(params[0]) or params[0].startswith("(")):
            index = self._output_index(params[0])
            params = params[1:]
        if len(params) > 2:
            raise _Error(-108)
        spec = self.specs[index]
        low, high = spec.voltage_range
        voltage = self._number(params[0], "V", low, high, 0.0) if params else None
        current = self._number(params[1], "A", 0.0, spec.max_current_a, spec.max_current_a) if len(params) > 1 else None
        if voltage is not None:  # both checked before either is set
            self._store_voltage(index, voltage)
        if current is not None:
            self.currents[index] = current
        self._drive_led()

    def _query_apply(self, params: list[str]) -> str:
        if len(params) > 1:
            raise _Error(-108)
        index = self._output_index(params[0]) if params else self.selected
        return f'"{self.voltages[index]:.6f},{self.currents[index]:.6f}"'

    # -- outputs ---------------------------------------------------------------------------------------
    def _set_output_state(self, params: list[str]) -> None:
        if not params:
            raise _Error(-109)
        if len(params) > 2:
            raise _Error(-108)
        on = self._boolean(params[0])
        if len(params) == 2:
            indices = self._channel_list(params[1])
            if indices is None:
                raise _Error(-104)
        else:
            indices = list(range(len(self.specs)))
        if on and self.lamp.interlock_open:
            raise _Error(-221)
        for index in indices:
            self.states[index] = on
        self._drive_led()

    def _query_output_state(self, params: list[str]) -> str:
        if len(params) > 1:
            raise _Error(-108)
        indices = self._channel_list(params[0]) if params else [self.selected]
        if indices is None:
            raise _Error(-104)
        if self.states[self.led] and self.led in indices and self.world.clock.instant:
            self.lamp.is_warm()  # observing completes the warm-up in instant mode
        return ",".join("1" if self.states[i] else "0" for i in indices)

    def _set_tracking(self, params: list[str]) -> None:
        if len(params) != 1:
            raise _Error(-109 if not params else -108)
        self.tracking = self._boolean(params[0])
        names = [spec.name for spec in self.specs]
        if self.tracking and "P25V" in names and "N25V" in names:
            self.voltages[names.index("N25V")] = -self.voltages[names.index("P25V")]

    def _query_tracking(self, params: list[str]) -> str:
        self._no_params(params)
        return "1" if self.tracking else "0"

    def _measure_index(self, params: list[str]) -> int:
        if len(params) > 1:
            raise _Error(-108)
        return self._output_index(params[0]) if params else self.selected

    def _measure_voltage(self, params: list[str]) -> str:
        return f"{self._measured(self._measure_index(params))[0]:+.8E}"

    def _measure_current(self, params: list[str]) -> str:
        return f"{self._measured(self._measure_index(params))[1]:+.8E}"

    def _select(self, params: list[str]) -> None:
        if len(params) != 1:
            raise _Error(-109 if not params else -108)
        self.selected = self._output_index(params[0])

    def _query_select(self, params: list[str]) -> str:
        self._no_params(params)
        return self.specs[self.selected].name

    def _nselect(self, params: list[str]) -> None:
        if len(params) != 1:
            raise _Error(-109 if not params else -108)
        match = _NUMBER.match(params[0])
        if not match or match.group(2):
            raise _Error(-104)
        number = round(float(match.group(1)))
        if not 1 <= number <= len(self.specs):
            raise _Error(-222)
        self.selected = number - 1

    def _query_nselect(self, params: list[str]) -> str:
        self._no_params(params)
        return str(self.selected + 1)

    # -- system ----------------------------------------------------------------------------------------
    def _next_error(self, params: list[str]) -> str:
        self._no_params(params)
        if not self.errors:
            return '0,"No error"'
        code = self.errors.pop(0)
        return f'{code},"{ERRORS[code]}"'

    def _set_remote(self, params: list[str], remote: bool) -> None:
        self._no_params(params)
        self.remote = remote
