"""Run-time parameters onto a unit's ports: from a :class:`golden.frontend.FrontEndParams` or a
:class:`golden.pipeline.PipelineParams` to the input ports of whatever unit takes them."""
from types import SimpleNamespace

from golden.ground import GroundParams
from hdl.ground import GroundConfig
from hdl.regmap import config_fields, param_value
from sim.streams import Packer

__all__ = ["apply_config", "config_values"]


def _scalar_values(params):
    """(port, value) of the parameters outside the ground model present in ``params``: every
    register field of ``hdl.regmap.config_fields`` whose ``port`` is a plain pipeline input
    (the ground model's travel together as :data:`hdl.ground.GroundConfig`)."""
    if not hasattr(params, "frontend"):             # a front end's parameters
        params = SimpleNamespace(frontend=params)
    values = []
    for _reg, f in config_fields():
        if "." not in f.port:
            value = param_value(params, f)
            if value is not None:
                values.append((f.port, value))
    return values


async def apply_config(ctx, dut, params):
    """Drive every run-time parameter port ``dut`` has from ``params``."""
    gp = getattr(params, "frontend", params).ground
    for port in ("config", "ground"):
        cfg = getattr(dut, port, None)
        if cfg is not None and hasattr(cfg, "ref_x"):
            for name, _ in GroundParams.FIELDS:
                ctx.set(getattr(cfg, name), int(getattr(gp, name)))
    for name, value in [*_scalar_values(params), *_fixed(dut)]:
        if hasattr(dut, name):
            ctx.set(getattr(dut, name), value)


def _fixed(dut):
    """(port, value) of the registers a unit was built with beside the parameters: its
    ``fixed_config`` dict (for example the rectifier's ``rect_lo`` and ``rect_enable``)."""
    return list(getattr(dut, "fixed_config", {}).items())


def config_values(dut, params):
    """The run-time parameter ports of ``dut`` and their values (for the Verilator harness)."""
    gp = getattr(params, "frontend", params).ground
    values = {}
    for port in ("config", "ground"):
        cfg = getattr(dut, port, None)
        if cfg is not None and hasattr(cfg, "ref_x"):
            fields = {name: int(getattr(gp, name)) for name, _ in GroundParams.FIELDS}
            values[port] = Packer(GroundConfig).pack_int(**fields)
    for name, value in _scalar_values(params):
        if hasattr(dut, name):
            values[name] = int(value)
    for name, value in _fixed(dut):     # two's complement in the port's width
        values[name] = int(value) & ((1 << len(getattr(dut, name))) - 1)
    return values
