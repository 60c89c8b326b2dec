"""Spartan-3 targets: Yosys resource estimates (sim/flows/synth.py), the reference board platform
and its ISE build tree, the camera input adapter (hdl/platform.py)."""
import json
import re

import pytest

from hdl.platform import CAMERA_PINS, IIC_PINS, RobotBoardPlatform
from sim.flows.synth import (BUDGET, build_ise, carry_length, count_cells, longest_path, lut_breakdown,
                       lut_levels, synthesize, write_report)


def cell(t, ins, outs):
    """A netlist cell of type ``t`` with input and output ports ``{port: [bits]}``."""
    return {"type": t, "port_directions": {**{p: "input" for p in ins}, **{p: "output" for p in outs}},
            "connections": {**ins, **outs}}


def test_count_cells():
    n = count_cells({"LUT1": 2, "LUT2": 3, "LUT4": 5, "INV": 1, "FDRE": 7, "FDSE": 1,
                     "RAMB16_S18_S18": 2, "MULT18X18": 3, "MUXCY": 9, "XORCY": 8, "IBUF": 4})
    assert (n["LUT4"], n["INV"], n["FF"], n["RAMB16"], n["MULT18X18"], n["carry"]) == (11, 1, 8, 2, 3, 17)
    assert n["LUT_sites"] == n["LUT4"] == 11
    n = count_cells({"LUT3": 4, "RAM16X1D": 3, "RAM16X1S": 2})
    assert (n["LUT4"], n["LUTRAM"], n["LUT_sites"]) == (4, 5, 4 + 3 * 2 + 2)
    with pytest.raises(ValueError, match="RAM128X1D"):
        count_cells({"RAM128X1D": 1})


def test_breakdown_shares_a_lut_between_the_parts_it_feeds():
    # a.q -> L1 -> L2 -> a.r and b.s; L3 -> b.s; one RAM16X1D in b
    netlist = {"modules": {"t": {"cells": {
        "fa": cell("FDRE", {"D": [3]}, {"Q": [1]}),
        "l1": cell("LUT2", {"I0": [1]}, {"O": [2]}),
        "l2": cell("LUT2", {"I0": [2]}, {"O": [3]}),
        "fb": cell("FDRE", {"D": [4]}, {"Q": [5]}),
        "l3": cell("LUT3", {"I0": [2]}, {"O": [4]}),
        "b.mem.0": cell("RAM16X1D", {"D": [5]}, {"DPO": [6]}),
    }, "netnames": {"a.q": {"bits": [1]}, "a.r": {"bits": [3]}, "b.s": {"bits": [5]},
                    "$x": {"hide_name": 1, "bits": [2, 4, 6]}}}}}
    parts = lut_breakdown(netlist, "t", depth=1)
    # l2 feeds a (fa.D); l3 feeds b; l1 feeds both (half each); the RAM: 2 sites in b:
    # a 1.5 -> 2, b 3.5 -> 4, largest first
    assert list(parts.items()) == [("b", 4), ("a", 2)]


def test_lut_levels_ignores_carry_cells():
    # FF(1) -> LUT(2) -> MUXCY(3) -> MUXCY(4) -> LUT(5) -> INV(6) -> FF
    netlist = {"modules": {"t": {"cells": {
        "ff": cell("FDRE", {"D": [6]}, {"Q": [1]}),
        "a": cell("LUT2", {"I0": [1], "I1": [1]}, {"O": [2]}),
        "c0": cell("MUXCY", {"S": [2]}, {"O": [3]}),
        "c1": cell("MUXCY", {"CI": [3]}, {"O": [4]}),
        "b": cell("LUT3", {"I0": [4]}, {"O": [5]}),
        "n": cell("INV", {"I": [5]}, {"O": [6]}),
        "side": cell("LUT4", {"I0": [1]}, {"O": [7]}),
    }}}}
    assert lut_levels(netlist, "t") == 3
    netlist["modules"]["t"]["netnames"] = {"q": {"bits": [1]}, "$x": {"hide_name": 1, "bits": [2]}}
    assert longest_path(netlist, "t") == (3, ["q", "q"])
    assert carry_length(netlist, "t") == 2


@pytest.fixture(scope="module")
def color_counts(tmp_path_factory):
    return synthesize("color", tmp_path_factory.mktemp("synth"))


def test_color_estimate(color_counts):
    c = color_counts
    assert c["RAMB16"] == 1                 # the reciprocal table
    assert 2 <= c["MULT18X18"] <= 5         # two 8x17 products (Yosys also maps the luma weights)
    assert 100 < c["LUT4"] < 1500 and 100 < c["FF"] < 700
    assert 1 <= c["levels"] <= 20 and c["ltp"] >= c["levels"]
    assert c["carry_bits"] >= 8                  # at least the 8-bit luma sum's chain
    assert c["timing_ok"] == (c["levels"] <= 8 and c["carry_bits"] <= 16)
    assert len(c["deepest_path"]) == 2
    print(f"color estimate: {c}")


def test_report(tmp_path):
    color_counts = {"LUT4": 380, "LUT_sites": 400, "FF": 222, "RAMB16": 1, "MULT18X18": 5,
                    "levels": 10, "ltp": 33, "breakdown": {"track": 300, "conv": 100}}
    bus_counts = dict(color_counts, LUT_sites=12500, RAMB16=20)
    soc_counts = dict(color_counts, LUT4=13000, RAMB16=23, levels=7, core_levels={"picorv32": 9},
                      core_carry_bits={"picorv32": 31})
    path = write_report({"color": color_counts, "soc": soc_counts, "soc_bus": bus_counts},
                        tmp_path)
    report = json.loads(path.read_text())
    assert "ESTIMATES" in report["note"]
    assert report["budget"] == BUDGET
    assert set(report["designs"]["color"]) >= {"LUT4", "FF", "RAMB16", "MULT18X18", "levels"}
    md = (tmp_path / "report.md").read_text()
    assert md.startswith("# Spartan-3 resource ESTIMATES")
    assert f"| color | {color_counts['LUT4']} | 400 | {color_counts['FF']} |" in md
    assert "- **color**: track 300, conv 100" in md
    assert ("Budget of soc_bus (the chip less an external MicroBlaze's share): LUT_sites 12500 "
            "of 12000 (over by 500), RAMB16 20 of 20: DOES NOT FIT.") in md
    assert "Budget of soc (the whole chip, CPU inside): LUT4 13000 of 14000, RAMB16 23 of 24: fits." in md
    assert ("The core's own paths, not checked: picorv32 9 levels and a 31-bit carry chain." in md)
    assert "soc: `levels`, `carry_bits` and `timing_ok` count the paths outside the CPU core" in md


def test_cpu_core_paths_are_reported_apart(tmp_path):
    """The CPU alone: the core is kept as its own module, its cells counted, its own deep
    paths reported apart from the level check, which applies to the rest."""
    c = synthesize("cpu", tmp_path)
    assert c["RAMB16"] == 4                      # 8 KB of RAM; the register file in LUT RAM
    assert c["LUTRAM"] > 0 and 1000 < c["LUT4"] < 4000
    assert c["levels_outside"] == ["picorv32"]
    assert c["core_levels"]["picorv32"] > 8 and c["core_carry_bits"]["picorv32"] > 16
    assert c["levels"] <= 8 and c["carry_bits"] <= 16 and c["timing_ok"]
    core = c["breakdown"]["picorv32 (core)"]
    assert core > c["LUT_sites"] / 2 and sum(c["breakdown"].values()) == pytest.approx(
        c["LUT_sites"], abs=len(c["breakdown"]))


def test_platform_pins_are_distinct():
    pins = []
    for cam in CAMERA_PINS:
        for v in cam.values():
            pins += v.split()
    pins += [p for pair in IIC_PINS for p in pair]
    pins += ["T9", "L14", "T14", "N10", "R13", "T13", "K12", "P14", "L12", "N14", "P13", "N12", "P12", "P11"]
    assert len(pins) == len(set(pins)) == 2 * 9 + 2 + 14
    assert {CAMERA_PINS[0]["llc"], CAMERA_PINS[1]["llc"]} <= {"T9", "R9", "N8", "P8", "D9", "C9", "A8", "B8"}


def test_ise_tree(tmp_path):
    """The tree has the CPU: the core's Verilog beside the SoC's, both in the project, and the
    RAM's initial words (here a short image) in the SoC's Verilog."""
    image = [0x0000_0537, 0x1234_5678, 0x0000_006F]
    out = build_ise("soc", tmp_path, image=image)
    names = {p.name for p in out.iterdir()}
    assert {"top.v", "top.ucf", "top.xst", "top.prj", "build_top.sh", "picorv32.v"} <= names
    assert "verilog work picorv32.v" in (out / "top.prj").read_text()
    top = (out / "top.v").read_text()
    assert "picorv32 #(" in top and "module picorv32" not in top
    assert re.search(r"ram\[1\] = 32'd305419896;", top)      # 0x12345678
    assert "-p xc3s1000ft256-4" in (out / "top.xst").read_text()
    ucf = (out / "top.ucf").read_text()
    assert 'NET "clk50_0__io" LOC=T9;' in ucf and 'NET "bt656_0__llc__io" LOC=C9;' in ucf
    assert RobotBoardPlatform().device == "xc3s1000"
