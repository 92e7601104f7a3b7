"""The wiring figure of the board (docs/wiring.svg), drawn from the board project's pin map.

    python -m uavarm.wiring            # writes docs/wiring.svg
    python -m uavarm.wiring --check    # exit 1 if docs/wiring.svg is not what the pin map gives

Each signal's pin is read from firmware_stm32/manipulator.ioc (by its pin label, or for the
USB pins by their peripheral signal); where the pin sits on a NUCLEO-F411RE comes from ST's
UM1724 (NUCLEO_PINS, the same text as docs/board-project.md's pin map). Every wire is an SVG
group carrying its signal, pin, Nucleo connector and the terminal it goes to as data-
attributes, so tests/test_wiring.py can hold the figure to the .ioc and the docs.
"""
from __future__ import annotations

import argparse
import re
import sys
from dataclasses import dataclass
from html import escape
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IOC = ROOT / "firmware_stm32" / "manipulator.ioc"
FIGURE = ROOT / "docs" / "wiring.svg"

# Where a pin sits on a NUCLEO-F411RE (UM1724: Arduino connectors CN5/CN6/CN8/CN9, morpho CN7/CN10)
NUCLEO_PINS = {
    "PA8": "D7 = CN9-8 (CN10-23)",
    "PB6": "D10 = CN5-3 (CN10-17)",
    "PB8": "D15 = CN5-10 (CN10-3)",
    "PB9": "D14 = CN5-9 (CN10-5)",
    "PA11": "CN10-14",
    "PA12": "CN10-12",
    "PA6": "D12 = CN5-5 (CN10-13)",
    "PA5": "LD2 (green, on board)",
}
NUCLEO_POWER = "+5 V: CN6-5, +3V3: CN6-4, GND: CN6-6, CN6-7"


@dataclass(frozen=True)
class Wire:
    signal: str        # the .ioc's pin label, or its peripheral signal (USB)
    name: str          # what the figure calls it
    y: int             # row on the MCU's edge
    to: str            # "component: terminal"
    end_x: int         # x of that terminal (the wire runs straight along y)


WIRES = [
    Wire("SERVO_PWR", "servo supply enable", 170, "servo supply switch: IN", 400),
    Wire("SERVO_BUS", "servo bus DATA", 250, "AX-12A: DATA (pin 3)", 700),
    Wire("IMU_SCL", "IMU SCL (I2C1)", 330, "GY-521 (MPU-6050): SCL", 560),
    Wire("IMU_SDA", "IMU SDA (I2C1)", 360, "GY-521 (MPU-6050): SDA", 560),
    Wire("USB_OTG_FS_DM", "USB D-", 430, "USB connector: D-", 560),
    Wire("USB_OTG_FS_DP", "USB D+", 460, "USB connector: D+", 560),
    Wire("LED1", "LED1: fault", 520, "LED1 resistor: 1 kOhm", 380),
]
ON_BOARD = Wire("LED0", "LED0: enabled", 550, "LD2 on the board", 290)

MCU_RIGHT = 290


def ioc_pins(path: Path = IOC) -> dict[str, str]:
    """{pin label or signal: pin} of the .ioc (its PXn.GPIO_Label and PXn.Signal keys)."""
    pins = {}
    for key, value in re.findall(r"^(P[A-H]\d+)\.(?:GPIO_Label|Signal)=(.+)$", path.read_text(), re.M):
        pins.setdefault(value.strip(), key)
    return pins


def _text(x, y, s, size=11, anchor="start", weight="normal") -> str:
    return (f'<text x="{x}" y="{y}" font-size="{size}" text-anchor="{anchor}" '
            f'font-weight="{weight}">{escape(s)}</text>')


def _ground(x, y) -> str:
    """A ground symbol hanging from (x, y)."""
    return (f'<path d="M{x} {y} v8 M{x - 8} {y + 8} h16 M{x - 5} {y + 11} h10 M{x - 2} {y + 14} h4" '
            'stroke="black" fill="none"/>')


def _supply(x, y, label) -> str:
    """A supply rail symbol above (x, y)."""
    return f'<path d="M{x} {y} v-8 M{x - 7} {y - 8} h14" stroke="black" fill="none"/>' + \
        _text(x, y - 12, label, 10, "middle")


ZIGZAG = (6, -12, 12, -12, 12, -6)    # a resistor's sideways steps, one per sixth of its length


def _resistor_v(x, y0, y1) -> str:
    """A vertical resistor between y0 and y1 (y0 < y1): 5 px leads, a zigzag between."""
    step = (y1 - y0 - 10) / 6
    zig = " ".join(f"l{dx} {step:g}" for dx in ZIGZAG)
    return f'<path d="M{x} {y0} v5 {zig} L{x} {y1}" stroke="black" fill="none"/>'


def _resistor_h(x0, x1, y) -> str:
    """A horizontal resistor between x0 and x1 (x0 < x1)."""
    step = (x1 - x0 - 10) / 6
    zig = " ".join(f"l{step:g} {dy}" for dy in ZIGZAG)
    return f'<path d="M{x0} {y} h5 {zig} L{x1} {y}" stroke="black" fill="none"/>'


def _box(x, y, w, h, title, lines=()) -> str:
    out = [f'<rect x="{x}" y="{y}" width="{w}" height="{h}" fill="#f4f4f4" stroke="black"/>',
           _text(x + w // 2, y + 15, title, 11, "middle", "bold")]
    out += [_text(x + w // 2, y + 30 + 13 * k, line, 10, "middle") for k, line in enumerate(lines)]
    return "\n".join(out)


def render(pins: dict[str, str] | None = None) -> str:
    """The figure's SVG text; pins: {label or signal: pin} (default: the .ioc's)."""
    pins = ioc_pins() if pins is None else pins
    missing = [w.signal for w in WIRES + [ON_BOARD] if w.signal not in pins]
    if missing:
        raise KeyError(f"{IOC.name} has no pin labelled or signalled {', '.join(missing)}")
    unplaced = sorted({pins[w.signal] for w in WIRES + [ON_BOARD]} - set(NUCLEO_PINS))
    if unplaced:
        raise KeyError(f"{', '.join(unplaced)}: not in NUCLEO_PINS (add its connector from UM1724)")
    out = ['<svg xmlns="http://www.w3.org/2000/svg" width="940" height="600" viewBox="0 0 940 600" '
           'font-family="sans-serif">',
           '<rect width="940" height="600" fill="white"/>',
           _text(470, 24, "uavarm board wiring (NUCLEO-F411RE; drawn from manipulator.ioc by python -m uavarm.wiring)",
                 13, "middle", "bold"),
           _box(30, 50, MCU_RIGHT - 30, 530, "STM32F411RE (NUCLEO-F411RE)",
                ["pin, Nucleo connector (UM1724)"]),
           _text(40, 110, "power:", 10), _text(40, 124, NUCLEO_POWER, 9),
           _text(40, 138, "all grounds common", 9)]
    for w in WIRES + [ON_BOARD]:
        pin = pins[w.signal]
        nucleo = NUCLEO_PINS[pin]
        out.append(f'<g class="wire" data-signal="{w.signal}" data-pin="{pin}" '
                   f'data-nucleo="{escape(nucleo)}" data-to="{escape(w.to)}">')
        out.append(_text(MCU_RIGHT - 8, w.y - 3, f"{pin}: {w.name}", 10, "end", "bold"))
        out.append(_text(MCU_RIGHT - 8, w.y + 10, nucleo, 9, "end"))
        if w.end_x > MCU_RIGHT:
            out.append(f'<circle cx="{MCU_RIGHT}" cy="{w.y}" r="3"/>')
            out.append(f'<path d="M{MCU_RIGHT} {w.y} H{w.end_x}" stroke="black" fill="none"/>')
        out.append("</g>")

    # the servo supply: PA8 drives a high-side switch's input, held low by a pull-down until it does
    out += [f'<circle cx="355" cy="170" r="2.5"/>', _resistor_v(355, 170, 215), _ground(355, 215),
            _text(349, 200, "10 kOhm", 9, "end"), _text(349, 211, "pull-down", 9, "end"),
            _box(400, 145, 140, 50, "servo supply switch", ["high side, 12 V"]),
            f'<path d="M470 145 V125" stroke="black"/>', _supply(470, 125, "+12 V servo supply"),
            _ground(470, 195),
            '<g class="wire" data-signal="servo supply" data-to="AX-12A: V+ (pin 2)">'
            '<path d="M540 170 H700" stroke="black" fill="none"/></g>',
            _text(620, 165, "12 V when PA8 is high", 9, "middle")]
    # the half-duplex bus: one DATA wire, pulled up to 5 V
    out += [f'<circle cx="620" cy="250" r="2.5"/>', _resistor_v(620, 205, 250), _supply(620, 205, "+5 V (CN6-5)"),
            _text(612, 222, "4.7 kOhm pull-up", 9, "end"), _text(612, 233, "(1 kOhm above 500 kbaud)", 9, "end"),
            _text(450, 244, "USART1_TX single-wire half-duplex, open drain; PB6 is 5 V tolerant", 9, "middle"),
            _box(700, 110, 210, 185, "AX-12A x 3, daisy-chained", ["3-pin cable: 1 GND, 2 V+, 3 DATA"]),
            _text(706, 174, "V+ (pin 2)", 10), _text(706, 254, "DATA (pin 3)", 10), _text(706, 284, "GND (pin 1)", 10),
            '<path d="M700 280 H680" stroke="black"/>', _ground(680, 280)]
    # the IMU breakout
    out += [_box(560, 315, 150, 60, "GY-521 (MPU-6050)", ["SCL, SDA; AD0 low: 0x68"]),
            '<path d="M710 330 H770" stroke="black"/>', _supply(770, 330, "+3V3 (CN6-4)"), _text(716, 327, "VCC", 9),
            '<path d="M710 360 H770" stroke="black"/>', _ground(770, 360), _text(716, 357, "GND, AD0", 9)]
    # USB to the drone's computer (the Nucleo's own USB is the ST-LINK)
    out += [_box(560, 410, 150, 65, "USB connector", ["to the drone's computer", "VBUS not connected"]),
            '<path d="M710 445 H770" stroke="black"/>', _ground(770, 445), _text(716, 442, "GND", 9)]
    # LED1 through its resistor to ground
    out += [_resistor_h(380, 430, 520), '<path d="M430 520 H450" stroke="black"/>',
            '<path d="M450 512 v16 l14 -8 z M464 512 v16" stroke="black" fill="white"/>',
            '<path d="M464 520 H480" stroke="black"/>', _ground(480, 520), _text(405, 510, "1 kOhm", 9, "middle"),
            _text(457, 545, "LED1", 9, "middle")]
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m uavarm.wiring", description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if the committed figure is stale")
    args = parser.parse_args(argv)
    try:
        text = render()
    except KeyError as exc:
        print(f"error: {exc.args[0]}", file=sys.stderr)
        return 1
    if args.check:
        if not FIGURE.exists() or FIGURE.read_text() != text:
            print(f"{FIGURE.relative_to(ROOT)} is stale: run python -m uavarm.wiring", file=sys.stderr)
            return 1
        return 0
    FIGURE.write_text(text)
    print(f"wrote {FIGURE.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
