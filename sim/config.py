"""Run-time parameters onto a unit's ports: from a :class:`golden.frontend.FrontEndParams` or a
:class:`golden.pipeline.PipelineParams` to the input ports of whatever unit takes them."""
from golden.ground import GroundParams
from hdl.ground import GroundConfig
from .streams import Packer

__all__ = ["apply_config", "config_values"]


def _scalar_values(params):
    """(port, value) of the Sobel, free-space and matcher parameters present in ``params``."""
    fp = getattr(params, "frontend", params)
    sp = fp.sobel
    values = [("threshold", sp.threshold), ("ratio", sp.ratio), ("nms", int(sp.nms)),
              ("band_w", fp.free.band_w), ("run_r", fp.free.run_r)]
    if hasattr(params, "right_threshold"):
        right = sp.threshold if params.right_threshold is None else params.right_threshold
        values.append(("right_threshold", right))
    mp = getattr(params, "matcher", None)
    if mp is not None:
        values += [("d_min", mp.d_min), ("d_max", mp.d_max), ("uniqueness", mp.uniqueness),
                   ("mode_full", int(mp.mode == "full")), ("widen", int(mp.widen)),
                   ("drop_mode", 0)]
    return values


async def apply_config(ctx, dut, params):
    """Drive every run-time parameter port ``dut`` has from ``params``."""
    gp = getattr(params, "frontend", params).ground
    for port in ("config", "ground"):
        cfg = getattr(dut, port, None)
        if cfg is not None and hasattr(cfg, "ref_x"):
            for name, _ in GroundParams.FIELDS:
                ctx.set(getattr(cfg, name), int(getattr(gp, name)))
    for name, value in _scalar_values(params):
        if hasattr(dut, name):
            ctx.set(getattr(dut, name), value)


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
    return values
