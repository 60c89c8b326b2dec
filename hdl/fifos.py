"""FIFOs whose storage is distributed RAM.

Yosys maps a memory of a few words but many bits to block RAM (two RAMB16 for the matcher's
59-bit, 8-word output FIFO; one even for a 16-word clock-domain FIFO, for its two clocks), where
LUT RAM costs two LUT sites a bit (RAM16X1D); the ``ram_style`` attribute on the storage keeps
it in LUTs.
"""
from amaranth.lib.fifo import AsyncFIFO, SyncFIFOBuffered

__all__ = ["DistributedSyncFIFOBuffered", "DistributedAsyncFIFO"]


class _DistributedStorage:
    """Mixin: the FIFO's ``storage`` memory in distributed RAM."""

    def elaborate(self, platform):
        m = super().elaborate(platform)
        m.submodules["storage"].attrs["ram_style"] = "distributed"
        return m


class DistributedSyncFIFOBuffered(_DistributedStorage, SyncFIFOBuffered):
    """``SyncFIFOBuffered`` with its storage in distributed RAM."""


class DistributedAsyncFIFO(_DistributedStorage, AsyncFIFO):
    """``AsyncFIFO`` with its storage in distributed RAM."""
