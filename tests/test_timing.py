"""``make timing`` (sim/flows/timing.py): the ECP5 place-and-route flow, run on one small unit so the
flow cannot rot (the full run over every design and three seeds is part of ``make bench``)."""
import json
import re

import pytest

from sim.designs import registered
from sim.flows.timing import SPARTAN3_SCALE, clock_name, clocks_of, main, wrapper_verilog


def test_wrapper_covers_every_port():
    component, _ = registered("color")
    text = wrapper_verilog("color", component)
    # every port of the design is connected, inputs from the shift register, outputs to q
    for port in ("i__valid", "i__payload", "i__ready", "o__valid", "o__payload", "o__ready",
                 "errors", "dropped", "rst"):
        assert re.search(rf"\.{port}\((sh|q)\[", text), port
    n_in = int(re.search(r"reg \[(\d+):0\] sh", text).group(1)) + 1
    n_out = int(re.search(r"wire \[(\d+):0\] q", text).group(1)) + 1
    assert n_in == 1 + 1 + 27 + 1 + 1      # rst, i valid + payload, o ready, frame_abort
    assert n_out == 1 + 1 + 27 + 16 + 32 + 1   # i ready, o valid + payload, errors, dropped,
    #                                            in_frame


def test_every_clock_domain_gets_its_pin_shift_register_and_fold():
    component, _ = registered("soc")
    text = wrapper_verilog("soc", component, clocks_of("soc"))
    assert "module timing_top(input wire clk, input wire cam0_clk, input wire cam1_clk," in text
    for k in (0, 1):
        # the camera's stream is fed and folded in its own clock domain, its clock is a pin
        assert f"always @(posedge cam{k}_clk)" in text
        assert re.search(rf"\.cam{k}__valid\(sh_cam{k}_clk\[", text)
        assert re.search(rf"\.cam{k}__ready\(q_cam{k}_clk\[", text)
        assert f".cam{k}_clk(cam{k}_clk)" in text
    assert clock_name("$glbnet$cam0_clk$TRELLIS_IO_IN") == "cam0_clk"
    assert clock_name("clk$TRELLIS_IO_IN") == "clk"


def test_bad_arguments(capsys):
    assert main(["--designs", "nosuch"]) == 2
    assert capsys.readouterr().err.startswith("error: unknown design")
    with pytest.raises(SystemExit, match="error: bad seed list"):
        main(["--seeds", "one"])
    assert main(["--designs", "color", "--jobs", "0"]) == 2
    assert capsys.readouterr().err.startswith("error: --jobs 0")


@pytest.mark.slow
def test_flow_on_color(tmp_path):
    # two designs through the pool of two processes: the larger (color) is run first, the
    # report keeps the order asked for
    assert main(["--designs", "uart,color", "--seeds", "1", "--jobs", "2", "--out",
                 str(tmp_path)]) == 0
    report = json.loads((tmp_path / "report.json").read_text())
    assert list(report) == ["uart", "color"]
    r = report["color"]
    assert set(r) >= {"fmax_mhz", "worst_mhz", "critical_path"}
    assert 10 < r["fmax_mhz"]["1"] < 500 and r["worst_mhz"] == r["fmax_mhz"]["1"]
    assert r["spartan3_estimate_mhz"] == round(r["worst_mhz"] * SPARTAN3_SCALE, 1)
    assert r["critical_path"]["from"].startswith("dut") or r["critical_path"]["to"].startswith("dut")
    md = (tmp_path / "report.md").read_text()
    assert "NOT Spartan-3" in md and "| color |" in md


def test_critical_path_is_the_core_clocks():
    """The report's path is the core clock's own (the figure it judges), not the first clock
    nextpnr lists."""
    from sim.flows.timing import critical_path

    def path(clk, a, b, delay):
        edge = f"posedge $glbnet${clk}$TRELLIS_IO_IN"
        return {"from": edge, "to": edge, "path": [
            {"type": "clk-to-q", "delay": 0.5, "from": {"cell": a}, "to": {"cell": a}},
            {"type": "routing", "delay": delay, "from": {"cell": a}, "to": {"cell": b}}]}

    rep = {"critical_paths": [path("cam1_clk", "c0", "c1", 7.0), path("clk", "k0", "k1", 11.0)]}
    assert critical_path(rep) == {"from": "k0", "to": "k1", "delay_ns": 11.5, "logic_ns": 0.5,
                                  "routing_ns": 11.0, "logic_cells": 0}
    rep["critical_paths"].pop()
    assert critical_path(rep)["from"] == "c0"


def test_utilisation_from_the_log():
    from sim.flows.timing import _fit, utilisation
    log = ("Info: Device utilisation:\n"
           "Info: \t          TRELLIS_IO:       5/    197     2%\n"
           "Info: \t              DP16KD:      39/     56    69%\n"
           "Info: \t          MULT18X18D:      23/     28    82%\n"
           "Info: \t          TRELLIS_FF:   16441/  24288    67%\n"
           "Info: \t        TRELLIS_COMB:   21720/  24288    89%\n")
    use = utilisation(log)
    assert use == {"DP16KD": [39, 56], "MULT18X18D": [23, 28], "TRELLIS_FF": [16441, 24288],
                   "TRELLIS_COMB": [21720, 24288]}
    assert _fit(use) == "21,720 / 16,441 / 39 / 23 of 24,288 / 24,288 / 56 / 28"
    use["DP16KD"] = [57, 56]
    assert _fit(use).endswith("does not fit**")


def test_each_design_is_placed_on_its_part(tmp_path, monkeypatch):
    """The chip with rectifiers is placed on the 45F (the 25F lacks the logic cells), the rest
    on the board's 25F; nextpnr gets the part's device option."""
    from sim.designs import SYSTEM_DESIGNS, all_designs
    from sim.flows import timing
    parts = {n: timing.part_of(n) for n in all_designs()}
    assert parts["soc"] == parts["color"] == "LFE5U-25F"
    assert parts["soc_rect"] == parts["soc_rect2"] == "LFE5U-45F"
    monkeypatch.setattr(SYSTEM_DESIGNS["soc"], "ecp5_part", "LFE5U-99F")
    with pytest.raises(ValueError, match="unknown ECP5 part 'LFE5U-99F'"):
        timing.part_of("soc")
    cmds = []

    def fake_run(cmd, cwd, log_name):
        cmds.append(cmd)
        (tmp_path / "nextpnr_seed1.log").write_text("")
        (tmp_path / "pnr_seed1.json").write_text(json.dumps(
            {"fmax": {"clk$TRELLIS_IO_IN": {"achieved": 90.0}}}))
        return 1.0
    monkeypatch.setattr(timing, "_run", fake_run)
    netlist = tmp_path / "netlist.json"
    assert timing.place_and_route(netlist, 1, "LFE5U-45F")[0] == {"clk": 90.0}
    assert timing.place_and_route(netlist, 1)[0] == {"clk": 90.0}
    assert [c[1] for c in cmds] == ["--45k", "--25k"]
