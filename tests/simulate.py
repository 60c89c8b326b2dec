"""Runs one testbench on a clocked design, for the tests of small units."""
from amaranth.sim import Simulator


def simulate(dut, bench, period=1e-6):
    """Simulates ``dut`` with its ``sync`` clock of ``period`` seconds until ``bench`` returns."""
    sim = Simulator(dut)
    sim.add_clock(period)
    sim.add_testbench(bench)
    sim.run()
