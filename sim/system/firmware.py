"""The firmware image of the SoC's RISC-V core: build it (``make -C firmware rv32``), read its
sections and its memory words.

``build_image()`` runs the cross build (cheap when up to date), serialised with the host
build's lock; ``build_image(floor_line, defines, rect_table, core)`` a variant with the
installed camera's floor line, macros of its own (a test's shorter timeouts), a calibrated
rig's rectification table or for another of the CPU's cores (:data:`hdl.cpu.CORES`) in a
folder of its own; ``sections()``
gives the ELF's loaded sections and their sizes (``size -A``);
``image_words()`` the little-endian 32-bit words of ``firmware.bin``, the block RAM contents
:class:`hdl.cpu.RiscvCPU` starts from.
"""
from __future__ import annotations

import fcntl
import subprocess
from pathlib import Path

from sim.paths import ROOT

__all__ = ["BUILD", "ELF", "BIN", "HEX", "LOADED", "RAM_BYTES", "STACK_BYTES", "build_image",
           "variant_dir", "sections", "image_bytes", "image_words"]

BUILD = ROOT / "build" / "firmware"
ELF = BUILD / "firmware.elf"
BIN = BUILD / "firmware.bin"
HEX = BUILD / "firmware.hex"
#: the sections that occupy the core's memory (code, read-only data, data, bss)
LOADED = (".text", ".rodata", ".data", ".bss")
RAM_BYTES = 8192                    #: firmware/Makefile FIRMWARE_RAM, the "compact" core's
STACK_BYTES = 720                   #: firmware/Makefile FIRMWARE_STACK


class FirmwareBuildError(RuntimeError):
    """The cross build failed (its output is the message)."""


def variant_dir(floor_line=None, defines=None, rect_table=None, core="compact") -> Path:
    """The folder of the image built with the installed camera's ``floor_line``
    (``golden.floor.FloorLine``), ``defines`` (``{macro: value}``), ``rect_table`` (the
    text of a ``rect_table.h``) and for ``core`` (a name in :data:`hdl.cpu.CORES`); none and
    the chip's ``"compact"`` core: the production image, :data:`BUILD`; otherwise
    ``build/firmware/variants/<hash of all four>/``, which also holds the variant's
    generated headers."""
    if floor_line is None and not defines and rect_table is None and core == "compact":
        return BUILD
    import hashlib
    key = repr((floor_line, sorted((defines or {}).items()), core))
    if rect_table is not None:
        key += rect_table
    return BUILD / "variants" / hashlib.sha256(key.encode()).hexdigest()[:12]


def _write(path: Path, text: str):
    """``text`` into ``path`` unless it already holds it (an unchanged table rebuilds nothing)."""
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def build_image(floor_line=None, defines=None, rect_table=None, core="compact") -> Path:
    """``make -C firmware rv32``: build/firmware/firmware.{elf,bin,hex,size}; returns the .bin.
    With a ``floor_line`` (``golden.floor.FloorLine``, the installed camera's) the image takes
    it from a generated table (``sim/flows/floor_table.py``) instead of the committed one;
    ``defines`` (``{macro: value}``, e.g. ``{"RADIO_RETRY_PERIODS": "1u"}``) build a variant
    with those ``-D`` macros (``FIRMWARE_DEFS``, only macros the sources give a default with
    ``#ifndef``); ``rect_table`` (a ``rect_table.h``'s text, ``sim.flows.rect_table.render``)
    replaces ``firmware/include/rect_table.h`` (both through ``GEN_DIR``), so the image checks and
    enables the rectifier for that calibration; ``core`` (a name in :data:`hdl.cpu.CORES`)
    builds for that core's instruction set and RAM. Any goes to :func:`variant_dir` (its
    ``.elf`` beside the returned ``.bin``). Raises :class:`FirmwareBuildError` with the build's output when it fails (no
    cross compiler: ``make setup`` installs it)."""
    from hdl.cpu import CORES
    config = CORES[core]
    BUILD.mkdir(parents=True, exist_ok=True)
    cmd = ["make", "-s", "-C", str(ROOT / "firmware"), "rv32", f"RV_MARCH={config.march}",
           f"FIRMWARE_RAM={config.ram_bytes}"]
    folder = variant_dir(floor_line, defines, rect_table, core)
    with open(BUILD / ".build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if folder != BUILD:
            folder.mkdir(parents=True, exist_ok=True)
            cmd.append(f"RV_BUILD={folder}")
        if floor_line is not None:
            from sim.flows.floor_table import render
            _write(folder / "floor_table.h", render(floor_line))
        if rect_table is not None:
            _write(folder / "rect_table.h", rect_table)
        if floor_line is not None or rect_table is not None:
            cmd.append(f"GEN_DIR={folder}")
        if defines:
            cmd.append("FIRMWARE_DEFS=" + " ".join(f"-D{k}={v}" for k, v in sorted(defines.items())))
        r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise FirmwareBuildError(f"make -C firmware rv32 failed:\n{r.stdout}{r.stderr}")
    return folder / BIN.name


def sections(elf: Path = ELF) -> dict:
    """``{section: bytes}`` of the loaded sections (:data:`LOADED`) of the image."""
    out = subprocess.run(["riscv64-unknown-elf-size", "-A", str(elf)], capture_output=True,
                         text=True, check=True).stdout
    sizes = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0] in LOADED:
            sizes[parts[0]] = int(parts[1])
    return {name: sizes.get(name, 0) for name in LOADED}


def image_bytes(elf: Path = ELF) -> int:
    """Code, data and bss: the memory the image occupies below the stack."""
    return sum(sections(elf).values())


def image_words(path: Path = BIN) -> list[int]:
    """The 32-bit little-endian words of a ``.bin`` image (the last one zero-padded)."""
    data = Path(path).read_bytes()
    data += bytes(-len(data) % 4)
    return [int.from_bytes(data[i:i + 4], "little") for i in range(0, len(data), 4)]
