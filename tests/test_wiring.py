"""The wiring figure (docs/wiring.svg, `python -m uavarm.wiring`) against the pin map it is
drawn from: the committed figure is what the script draws now; each wire's pin is the
.ioc's pin of its signal; each Nucleo connector is docs/board-project.md's; every pin the
board wires is drawn; and each wire ends where the docs' pin map says it goes.

Oracles: firmware_stm32/manipulator.ioc (the pins CubeMX configures), docs/board-project.md's
pin map table (signal, pin, NUCLEO-F411RE connector from UM1724, note)."""
import re
import xml.etree.ElementTree as ET

import pytest

from conftest import ROOT
from test_stm32_project import ioc
from uavarm import wiring

SVG = "{http://www.w3.org/2000/svg}"


def wires(text: str) -> dict[str, dict]:
    """{signal: the wire group's data- attributes} of the figure's pin wires."""
    root = ET.fromstring(text)
    return {g.get("data-signal"): {k.removeprefix("data-"): v for k, v in g.attrib.items()}
            for g in root.iter(f"{SVG}g") if g.get("class") == "wire" and g.get("data-pin")}


def docs_pin_map() -> dict[str, tuple[str, str, str]]:
    """{pin: (signal, Nucleo connector, note)} of docs/board-project.md's pin map table."""
    text = (ROOT / "docs" / "board-project.md").read_text()
    table = text[text.index("## Pin map"):].split("\n\n")[2]
    rows = {}
    for line in table.splitlines()[2:]:
        signal, pin, nucleo, note = (c.strip() for c in line.strip("|").split("|"))
        rows[pin] = (signal, nucleo, note)
    return rows


def test_the_committed_figure_is_what_the_pin_map_draws():
    assert wiring.main(["--check"]) == 0, "run python -m uavarm.wiring"


def test_every_wired_pin_is_the_iocs_and_every_connector_the_docs():
    k = ioc()
    drawn = wires(wiring.FIGURE.read_text())
    # what the board wires: every labelled output and peripheral pin, the USB pins (the
    # configuration inputs CFG0-2 are solder bridges on the board itself)
    labelled = {v: key.split(".")[0] for key, v in k.items() if key.endswith(".GPIO_Label")}
    wired = {label for label in labelled if not label.startswith("CFG")} | {"USB_OTG_FS_DM", "USB_OTG_FS_DP"}
    assert set(drawn) == wired
    pins = {**labelled, **{k[f"{p}.Signal"]: p for p in ("PA11", "PA12")}}
    docs = docs_pin_map()
    for signal, wire in drawn.items():
        assert wire["pin"] == pins[signal], signal
        assert wire["nucleo"] == docs[wire["pin"]][1], signal


# Where each signal goes, as the docs' pin map says (its note column names the part and pin)
DESTINATIONS = {"SERVO_PWR": ("high-side switch", "servo supply switch: IN"),
                "SERVO_BUS": ("AX-12A DATA pin (pin 3", "AX-12A: DATA (pin 3)"),
                "IMU_SCL": ("GY-521 SCL", "GY-521 (MPU-6050): SCL"),
                "IMU_SDA": ("GY-521 SDA", "GY-521 (MPU-6050): SDA"),
                "LED1": ("LED + 1 kΩ to GND", "LED1 resistor: 1 kOhm")}


@pytest.mark.parametrize("signal", sorted(DESTINATIONS))
def test_each_wire_ends_where_the_docs_pin_map_says(signal):
    wire = wires(wiring.FIGURE.read_text())[signal]
    note_says, drawn_to = DESTINATIONS[signal]
    assert note_says in docs_pin_map()[wire["pin"]][2] and wire["to"] == drawn_to


def test_the_bus_pull_up_and_the_supply_switch_are_drawn_as_the_docs_give_them():
    text = wiring.FIGURE.read_text()
    docs = docs_pin_map()
    assert "pull-up 4.7 kΩ to 5 V" in docs["PB6"][2] and "4.7 kOhm pull-up" in text and "+5 V (CN6-5)" in text
    assert "pull-down on the driver input" in docs["PA8"][2] and "pull-down" in text
    assert re.search(r'data-signal="servo supply" data-to="AX-12A: V\+ \(pin 2\)"', text)


def test_a_pin_moved_in_the_ioc_moves_in_the_figure_or_is_refused():
    pins = wiring.ioc_pins()
    moved = wires(wiring.render({**pins, "LED1": "PA5", "LED0": "PA6"}))
    assert moved["LED1"]["pin"] == "PA5" and moved["LED1"]["nucleo"] == wiring.NUCLEO_PINS["PA5"]
    with pytest.raises(KeyError, match="PC7: not in NUCLEO_PINS"):
        wiring.render({**pins, "SERVO_PWR": "PC7"})
