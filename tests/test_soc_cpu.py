"""The SoC with its CPU inside, on the boards: the Spartan-3 ISE tree and the ECP5 build plan
include the core's Verilog and the RAM initialised with the firmware image."""
from hdl.platform import BoardTop, RobotBoardPlatform
from hdl.soc import SystemSoC
from sim.designs import silenced
from sim.system import firmware


def test_ise_tree_has_the_cpu_and_its_image(tmp_path):
    firmware.build_image()
    words = firmware.image_words()
    plan = RobotBoardPlatform().build(BoardTop(soc=dict(cpu="picorv32", image=words)),
                                      name="top", build_dir=str(tmp_path), do_build=False)
    files = plan.files
    assert "picorv32.v" in files and "module picorv32" in files["picorv32.v"]
    top = files["top.v"]
    assert "picorv32" in top
    # the image's first word (the start-up code) is in the RAM's initial contents
    assert f"ram[0] = 32'd{words[0]};" in top and f"ram[1] = 32'd{words[1]};" in top
    assert "picorv32.v" in files["top.prj"]


def test_soc_without_cpu_keeps_its_bus_port():
    soc = silenced(SystemSoC())
    assert "bus" in soc.signature.members and "cpu_idle" not in soc.signature.members
    soc = silenced(SystemSoC(cpu="picorv32"))
    assert "bus" not in soc.signature.members and "cpu_idle" in soc.signature.members
    soc = silenced(SystemSoC(cpu="picorv32", monitor=True))
    assert all(m.flow.name == "Out" for m in soc.signature.members["monitor"].signature.members.values())
