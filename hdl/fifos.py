"""FIFOs whose storage is distributed RAM.

Yosys maps a memory of a few words but many bits to block RAM (two RAMB16 for a 59-bit, 8-word
FIFO), where LUT RAM costs two LUT sites a bit (RAM16X1D); the ``ram_style`` attribute on the
storage keeps it in LUTs.
"""
from amaranth.lib.fifo import SyncFIFOBuffered

__all__ = ["DistributedSyncFIFOBuffered"]


class DistributedSyncFIFOBuffered(SyncFIFOBuffered):
    """``SyncFIFOBuffered`` with its storage in distributed RAM."""

    def elaborate(self, platform):
        m = super().elaborate(platform)
        m.submodules["storage"].attrs["ram_style"] = "distributed"
        return m
