"""Run a unit of :mod:`sim.units` on a backend and count mismatches with golden."""
import threading

from amaranth.lib.wiring import Out

from sim.config import apply_config, config_values
from sim.errors import CliError, InternalError, RtlFailure
from sim.streams import run_streams, Deadlock

__all__ = ["run_unit", "STALL_PROBABILITY"]

#: Idle and backpressure probability per cycle when stalls are requested.
STALL_PROBABILITY = 0.25


def run_unit(unit, job, *, backend="amaranth", stall_seed=None, timeout=100000, dut=None):
    """Simulate ``unit`` on ``job`` with ``backend`` (on ``dut`` when given, else on a new
    ``unit.make(job)``). Returns a dict with ``mismatches``, ``cycles`` (first input word offered
    to last output taken), ``words`` (output words per port), ``status`` (every output port that
    is not a stream, at the end), ``simulated_cycles`` and ``seconds`` (every simulated cycle
    and the simulator's own run time, None where the backend has no such figure) and ``dut``.
    Backends: ``amaranth``, ``verilator`` (the C++ harness), ``icarus`` and ``ghdl`` (cocotb),
    and ``cocotb-verilator`` (cocotb on Verilator, for speed comparisons). A hung design raises
    :class:`RtlFailure`, a missing or failing simulator :class:`InternalError`."""
    stalls = STALL_PROBABILITY if stall_seed is not None else 0.0
    seed = stall_seed or 0
    dut = unit.make(job) if dut is None else dut
    if backend == "amaranth":
        status_ports = [name for name, m in dut.signature.members.items()
                        if m.is_port and m.flow == Out]
        try:
            run = run_streams(dut, unit.words(job), unit.outputs(job), seed=seed, idle=stalls,
                              stall=stalls, setup=lambda ctx: apply_config(ctx, dut, job.params),
                              timeout=timeout, probes=status_ports)
        except Deadlock as e:
            raise RtlFailure(f"{unit.name} deadlocked: {e}") from None
        words, cycles, status = run.words, run.cycles, dict(run.probes)
        simulated, seconds = run.cycles, None
    elif backend == "verilator":
        from sim.backends.verilator import run_verilator, VerilatorError
        # The harness is another process: compute the golden frames while it runs.
        golden = threading.Thread(target=lambda: job.golden, daemon=True)
        golden.start()
        try:
            run = run_verilator(dut, inputs=unit.words(job), out_frames=unit.outputs(job),
                                runtime=config_values(dut, job.params), seed=seed, idle=stalls,
                                stall=stalls, timeout=timeout, name=unit.name)
        except VerilatorError as e:
            raise InternalError(str(e).splitlines()[0]) from None
        except Deadlock as e:
            raise RtlFailure(f"{unit.name} deadlocked: {e}") from None
        finally:
            golden.join()
        words, cycles, status = run.outputs, run.cycles, run.status
        simulated, seconds = run.total_cycles, run.seconds
    elif backend in ("icarus", "ghdl", "cocotb-verilator"):
        # cocotb on the exported Verilog (Icarus, Verilator) or on the generated VHDL (GHDL)
        from sim.backends.cocotb import simulate, SimulatorMissing
        try:
            run = simulate(dut, backend.removeprefix("cocotb-"), name=unit.name, inputs=unit.words(job),
                           out_frames=unit.outputs(job), runtime=config_values(dut, job.params),
                           seed=seed, idle=stalls, stall=stalls, timeout=timeout)
        except SimulatorMissing as e:
            raise InternalError(str(e).splitlines()[0]) from None
        except Deadlock as e:
            raise RtlFailure(f"{unit.name} deadlocked: {e}") from None
        words, cycles, status = run.outputs, run.cycles, run.status
        simulated, seconds = run.cycles, run.seconds
    else:
        raise CliError(f"unknown backend {backend!r}")
    return {"mismatches": unit.mismatches(job, words, dut), "cycles": cycles, "words": words,
            "status": status, "simulated_cycles": simulated, "seconds": seconds, "dut": dut}
