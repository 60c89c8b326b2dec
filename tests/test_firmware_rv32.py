"""The firmware's image for the SoC's RISC-V core: it cross-compiles with Debian's
riscv64-unknown-elf-gcc and picolibc (installed by ``make setup``) and fits the core's memory
with its stack."""
import subprocess

from sim.system import firmware


def test_image_builds_and_fits_memory_with_stack():
    firmware.build_image()
    sizes = firmware.sections()
    assert sizes[".text"] > 1000
    total = firmware.image_bytes()
    assert total == sum(sizes.values())
    assert total <= firmware.RAM_BYTES - firmware.STACK_BYTES, sizes
    print({**sizes, "total": total})


def _instructions(elf):
    """The ELF's header text and its instructions as (encoding, mnemonic) pairs."""
    head = subprocess.run(["riscv64-unknown-elf-readelf", "-h", str(elf)],
                          capture_output=True, text=True, check=True).stdout
    dis = subprocess.run(["riscv64-unknown-elf-objdump", "-d", str(elf)],
                         capture_output=True, text=True, check=True).stdout
    insns = [line.split("\t") for line in dis.splitlines() if line.count("\t") >= 2]
    return head, [(parts[1].strip(), parts[2].split()[0]) for parts in insns if parts[2].strip()]


def test_image_is_rv32ic_starting_at_zero():
    firmware.build_image()
    head, insns = _instructions(firmware.ELF)
    assert "ELF32" in head and "RISC-V" in head
    assert "Entry point address:               0x0" in head
    ops = {op for _, op in insns}
    # no multiply or divide instructions (the core has no M extension); compressed ones
    # (16-bit encodings) are used
    assert not ops & {"mul", "mulh", "mulhu", "div", "divu", "rem", "remu"}, ops
    assert sum(len(code) == 4 for code, _ in insns) > len(insns) // 3


def test_fast_core_image_has_no_compressed_instructions_and_fits_its_ram():
    """The image for the core without compressed instructions (hdl.cpu.CORES["fast"]): every
    instruction 32 bits, a build of its own, inside the core's 16 KB with the stack."""
    from hdl.cpu import CORES
    binary = firmware.build_image(core="fast")
    assert binary.parent != firmware.BUILD
    elf = binary.with_suffix(".elf")
    head, insns = _instructions(elf)
    assert "Entry point address:               0x0" in head
    assert insns and all(len(code) == 8 for code, _ in insns)
    total = firmware.image_bytes(elf)
    assert firmware.image_bytes() < total <= CORES["fast"].ram_bytes - firmware.STACK_BYTES


def test_words_and_hex_agree_with_the_binary():
    firmware.build_image()
    words = firmware.image_words()
    data = firmware.BIN.read_bytes()
    assert len(words) == (len(data) + 3) // 4
    assert words[0] == int.from_bytes(data[:4], "little")
    hexwords = [int(w, 16) for w in firmware.HEX.read_text().split()]
    assert hexwords == words


def test_delays_use_the_timer_not_a_loop():
    """Target delays write the timer's WAIT register: no calibrated busy loop remains."""
    src = (firmware.ROOT / "firmware" / "src" / "hal.c").read_text()
    target = src[src.index("#ifdef HAL_TARGET"):src.index("#else /* host build */")]
    delay = target[target.index("void hal_delay_us"):target.index("uint32_t hal_ticks")]
    assert "HAL_TIMER_WAIT_OFFSET" in delay and "volatile" not in delay
