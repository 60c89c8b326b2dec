"""Co-simulation: the firmware (host shared library) drives the RTL IIC master and register
block in Amaranth's simulator against two ADV7180 models (see sim/system/cosim/run.py)."""

import pytest

from sim.system.cosim import fwlib
from sim.system.cosim.run import SCENARIOS, check, run_scenario


@pytest.fixture(scope="module")
def lib():
    return fwlib.load()


@pytest.mark.slow
@pytest.mark.parametrize("scenario", SCENARIOS, ids=[s.name for s in SCENARIOS])
def test_cosim(lib, scenario):
    res = run_scenario(scenario, lib)
    lines = check(res, scenario, fwlib.init_table(lib))
    print(f"\n{scenario.name}: {res.cycles} cycles, {res.accesses} bus transfers, "
          f"{res.seconds:.1f} s")
    for line in lines:
        print(f"    {line}")
