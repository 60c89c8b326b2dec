"""System simulation with the CPU inside: the whole SoC (``hdl.soc.SystemSoC`` with
``cpu="picorv32"``) under Verilator, its core running the cross-compiled firmware
(``build/firmware/firmware.bin``, ``make -C firmware rv32``); no host firmware in the loop.

    python -m sim system [--cpu picorv32] [--scene S] [--frames N] [--fault F]

From BT.656 bytes to the radio UART's TX pin (``sim/system/harness/cpu_system.cpp``): the
cameras as in :mod:`sim.system.run`, two ADV7180 models on the IIC pins, the TX pin decoded
into bytes and those into XBee API frames (``station.radio.FrameDecoder``), an XBee model
answering the firmware's API-mode queries (AP = 2, MY = the robot's address) on the RX pin.

Checks (the JSON line):

``bit_exact``
    The records the SoC hands its band summary unit (``hdl.soc.SystemSoC`` ports
    ``record_valid``, ``record_word``) split into frames at the end-of-frame markers equal
    golden's (x, y, d) and floor flag frame for frame (with a fault: as :mod:`sim.system.run`,
    the frames before it and from the second pair after it). The firmware enables the floor
    flag with the installed camera's line (its image's ``floor_table.h``: the scene's line,
    ``sim.flows.floor_table.scene_line``, else FLOOR_LINE's reset value,
    ``hdl.regmap.RIG_FLOOR_LINE``) and learns none (``firmware/include/app.h`` APP_FLOOR_LEARN): golden flags by that line
    (``golden.floor.record_flags``: the obstacle feet kept, as the flag unit does); ``floor_points`` counts the flagged records, ``floor_line``
    is that line (slope, offset).
``radio_packets``, ``radio_exact``
    The packets decoded from the pin; each one's bands equal the firmware's summary rule
    (``golden.bands``: :func:`~golden.bands.band_values` of :func:`~golden.bands.merge_tops` of
    each frame's :func:`~golden.bands.frame_top`, floor points left out) over the frames that ended (their marker
    reached the unit) between the previous packet's first byte and this one's: the firmware
    merges each frame's summary as the unit publishes it and closes its summary right before
    sending. A frame it missed, or merged twice, makes a packet differ. ``radio_frames``: the
    frames each packet covers; ``radio_cycles``: the core cycle of each packet's first byte on
    the pin; ``radio_health``: each packet's health counters that are not 0
    (``station.wire`` field names, ``cam_errors`` as left and right);
    ``radio_cameras_lost``: the cameras each packet reports lost
    (``station.wire.lost_cameras``).
``camera_lost_changes``
    The loss watch's bits as the SoC computes them (HEALTH_STATUS left_lost bit 0,
    right_lost bit 1), independent of the firmware's reads: [core cycle, bits from then on]
    at each change. Cameras whose stream has ended are lost two field times after their last
    field start, so the packets of a run's end report both lost.
``rectified``, ``rect``
    With a calibrated rig (``rect``, :mod:`sim.system.rect`): the SoC holds the right
    camera's rectifier (and the left camera's, when the calibration rectifies both) with the
    rig's maps in their map memories, the image the rig's table; golden
    is the rectified pipeline (``golden.rectify.rectified_pipeline_frames``) with the
    registers the firmware sets, or the plain one when the rig's warp exceeds the build (the
    firmware then cannot enable it). ``rectified``: packets came and none carries the
    RECT_FAULT flag (the firmware checked the map and enabled the rectifier); ``rect``: that
    flag (``rect_fault``), the rows less one the rig's warp needs (``need_span``) and the
    build's line buffer holds (``build_span``), and the cameras rectified (``cameras``:
    ``right`` or ``both``).
``cpu``
    ``core``, ``configuration`` (the core's, :data:`hdl.cpu.CORES`: ``fast`` in a rectifying
    build), ``image_bytes`` (code, data and bss), ``sections``, ``instructions`` retired,
    ``busy_fraction`` (core cycles not asleep in a timer wait over all core cycles, from the
    firmware's enabling the video path to the end), ``cycles_per_record`` (those busy cycles
    per record the SoC produced), ``trapped``.

Health (``frames``, ``drops``, ``fifo_overflow``, ...) is the sum of the packets' health fields:
what the firmware reported. The run goes on after the last frame until a packet has covered it.

Faults:

``camera-lost-left``
    The left decoder sends nothing for :data:`LOST_FIELDS` fields, from the end of field 0
    (right after the EAV that ends its last active line: a BT.656 decoder ends a line at the
    next EAV, so field 0 is whole) to the same point of field ``1 + LOST_FIELDS``; the bytes of
    that time are lost, then the stream goes on. The right camera's fields of that time have no
    partner: the pairing drops them (``drops``, rule 2 of ``golden.pairing``). Bit-exact: the
    pipeline sees the pairs (L0, R0), (L5, R5), ... of identical fields, so the frames out equal
    golden's first ``frames - LOST_FIELDS``, and the loss is counted in the packets' health
    (``drops``) and told by a packet (CAMERA_LOST with the left camera's LOCKED bit clear).
``iic-nack``
    The right decoder never answers its IIC address: counted when the firmware addressed it
    and every packet's health carries the DECODER_FAULT flag. ``decoders_addressed``: how
    often the firmware addressed each decoder (its start-up, its retries).
``no-radio-module``
    Nothing answers the XBee queries: counted when every packet's health carries the
    RADIO_FAULT flag (``station.wire.HEALTH_FLAGS``). ``radio_queries``: the core cycles of the
    API-mode AT query frames seen on the TX pin (the start-up configuration's and the
    firmware's later probes of the module).
"""
from __future__ import annotations

import ctypes as C
import time

from golden.floor import FloorParams, record_flags
from golden.pipeline import default_params, pipeline_frames
from hdl import regmap
from sim.system.run import LOST_FIELDS, camera_lost_span

__all__ = ["CPU_FAULTS", "LOST_FIELDS", "build_cpu_system", "run_cpu_system"]

CPU_FAULTS = ("camera-lost-left", "iic-nack", "no-radio-module")
UART_DIVISOR = 434                  #: 115200 baud at 50 MHz (the firmware's BAUD)
XBEE_ROBOT_ADDR = 0x0002            #: firmware/include/xbee.h
REPORT_PS = 100_000_000_000         #: the firmware's report period, 100 ms
SLICE_PS = 2_000_000_000            #: host poll period of the simulation, 2 ms
_INSTRET = "soc__DOT__cpu__DOT__core__DOT__count_instr"
_RAM = "soc__DOT__cpu__DOT__ram"
_LOST = ("soc__DOT__health_status_left_lost", "soc__DOT__health_status_right_lost")

_libs = {}


def build_cpu_system(soc_params):
    """``build/system/cpu-<hash>/libcpusystem.so`` for SystemSoC(cpu="picorv32", monitor=True,
    **soc_params) (with ``rectify``, its map in the map memory) with an empty RAM (the harness loads the image: the model does not depend on
    the firmware); returns (path, build seconds), built once per process."""
    from hdl.cpu import verilog_text
    from hdl.soc import SystemSoC
    from sim.backends.verilator import VERILATOR_FLAGS
    from sim.designs import silenced
    from sim.flows.verilog import SIMULATION_PASSES, verilog_source
    from sim.system.run import HARNESS, verilated_library
    plain = _plain(soc_params)
    key = repr(sorted(plain.items()))
    if key in _libs:
        return _libs[key], 0.0
    soc = silenced(SystemSoC(cpu="picorv32", monitor=True, **soc_params))
    vlt = ('`verilator_config\npublic_flat_rd -module "picorv32" -var "count_instr"\n'
           'public_flat_rw -module "soc.cpu" -var "ram"\n'
           'public_flat_rd -module "soc" -var "health_status_*_lost"\n')
    files = {"cpu.vlt": vlt,
             "soc.v": verilog_source("soc", soc, plain, passes=SIMULATION_PASSES),
             "core0.v": verilog_text(),
             "cpu_system.cpp": (HARNESS.parent / "cpu_system.cpp").read_text()}
    lib, seconds = verilated_library(
        "cpu-", "libcpusystem.so", files, [*VERILATOR_FLAGS, "-Wno-TIMESCALEMOD"],
        f"-std=c++17 -fPIC -DINSTRET={_INSTRET} -DRAM={_RAM} -DLOST_LEFT={_LOST[0]} "
        f"-DLOST_RIGHT={_LOST[1]}", "the SoC with its CPU")
    _libs[key] = lib
    return lib, seconds


def _plain(soc_params):
    """``soc_params`` as plain values for the Verilog's header and the build's key: a
    rectifier's map (``rectify["nodes"]``, ``rectify_left["nodes"]``, arrays) as its
    SHA-256."""
    import hashlib
    plain = dict(soc_params)
    for key in ("rectify", "rectify_left"):
        rect = plain.get(key)
        if rect is not None and rect.get("nodes") is not None:
            nodes = hashlib.sha256(rect["nodes"].tobytes()).hexdigest()
            plain[key] = {**rect, "nodes": f"sha256:{nodes}"}
    return plain


def _load(path):
    lib = C.CDLL(str(path))
    lib.sys_init.argtypes = [C.c_char_p, C.c_uint64, C.c_char_p, C.c_uint64] + \
        [C.c_int64] * 5 + [C.c_uint32, C.c_int, C.c_int]
    lib.sys_camera_stop.argtypes = [C.c_int, C.c_int64, C.c_int64]
    lib.sys_run_until.argtypes = [C.c_int64]
    lib.sys_load_ram.argtypes = [C.POINTER(C.c_uint32), C.c_uint64]
    lib.sys_take_records.argtypes = [C.POINTER(C.c_uint64), C.POINTER(C.c_uint32), C.c_uint64]
    lib.sys_take_records.restype = C.c_uint64
    lib.sys_take_tx.argtypes = [C.POINTER(C.c_uint64), C.POINTER(C.c_uint8), C.c_uint64]
    lib.sys_take_tx.restype = C.c_uint64
    lib.sys_take_lost.argtypes = [C.POINTER(C.c_uint64), C.POINTER(C.c_uint8), C.c_uint64]
    lib.sys_take_lost.restype = C.c_uint64
    lib.sys_send_rx.argtypes = [C.c_char_p, C.c_uint64]
    for name in ("sys_core_cycles", "sys_idle_cycles", "sys_trap_cycles", "sys_instructions",
                 "sys_video_on_cycles", "sys_video_on_idle"):
        getattr(lib, name).restype = C.c_uint64
    lib.sys_time_ps.restype = C.c_int64
    lib.sys_decoder_addressed.restype = C.c_uint64
    lib.sys_decoder_addressed.argtypes = [C.c_int]
    return lib


def _xbee_answer(frame):
    """The XBee's answer to an API frame the firmware sent (an AT query), or None."""
    from station.radio import encode_frame
    from station.wire import API_AT_COMMAND, API_AT_RESPONSE
    if frame.api != API_AT_COMMAND or len(frame.data) < 3:
        return None
    fid, cmd = frame.data[0], bytes(frame.data[1:3])
    values = {b"AP": bytes([2]), b"MY": XBEE_ROBOT_ADDR.to_bytes(2, "big")}
    if cmd not in values:
        return None
    return encode_frame(bytes([API_AT_RESPONSE, fid]) + cmd + b"\x00" + values[cmd])


#: firmware/include/xbee.h: the guard time around "+++" and the wait for one response
XBEE_GUARD_US, XBEE_RESPONSE_US = 1_100_000, 200_000


def _macro(defines, name, default):
    """An integer macro of ``defines`` (``"10000u"``), or ``default``."""
    value = (defines or {}).get(name)
    return default if value is None else int(str(value).rstrip("uUlL"), 0)


def run_cpu_system(left, right, *, frames=5, fault=None, timing="ntsc", seed=1, floor_line=None,
                   defines=None, min_packets=1, rect=None):
    """Simulate with the CPU inside; returns the result dict (the JSON line's fields).
    ``floor_line``: the installed camera's floor line (``golden.floor.FloorLine``) the image is
    built with (None: the nominal rig's). ``defines``: macros of a firmware variant
    (:func:`sim.system.firmware.build_image`), e.g. shorter XBee waits for a test; None: the
    production image. The run ends once a packet has covered the last frame and at least
    ``min_packets`` packets came (or at a bound of the start-up, the streams and
    ``min_packets + 1`` report periods). ``rect`` (a :class:`sim.system.rect.SystemRect`):
    a calibrated rig's rectifiers in the SoC, their maps in the map memories, and the image built
    with its table; golden rectifies the cameras as the firmware can set them."""
    from sim.system import firmware
    from sim.system.run import (CAM1_PS, CAM_PERIOD_PS, CAM_PS, CORE_PS, FAULT_FIELD,
                                RIGHT_LEAD_BYTES, camera_streams)
    from golden.bands import band_values, frame_top, merge_tops
    from station.radio import FrameDecoder
    from station.wire import DEFAULT_MIN_SUPPORT, HEALTH_FLAGS, lost_cameras
    from station.wire import API_AT_COMMAND, API_TX16
    h, w = left.shape[:2]
    params = default_params(w, h)
    binary = (firmware.build_image(floor_line, defines) if rect is None else
              firmware.build_image(floor_line, defines, rect.table, rect.cpu_core))
    image = firmware.image_words(binary)
    sections = firmware.sections(binary.with_suffix(".elf"))
    ldata, rdata, lrgb, rrgb = camera_streams(left, right, frames, timing)
    rdata = bytes([0x80, 0x10] * (RIGHT_LEAD_BYTES // 2)) + b"\x80" * (RIGHT_LEAD_BYTES & 1) + rdata
    soc_params = dict(max_width=max(64, w), max_height=max(16, h), lines=h,
                      cost=params.matcher.cost)
    if rect is not None:
        soc_params.update(rect.soc_params)
    libpath, build_s = build_cpu_system(soc_params)
    lib = _load(libpath)

    if rect is not None and rect.golden is not None:
        from golden.rectify import rectified_pipeline_frames
        golden = rectified_pipeline_frames([lrgb] * frames, [rrgb] * frames, params, rect.golden,
                                           rect.golden_left)
    else:
        golden = pipeline_frames([lrgb] * frames, [rrgb] * frames, params)
    floor = FloorParams(mode="rig", initial=floor_line or regmap.RIG_FLOOR_LINE)
    want = [[(int(r["x"]), int(r["y"]), int(r["d"]), int(f)) for r, f in
             zip(g.records, record_flags(g.records, floor.initial, floor))]
            for g in golden]

    nack = 0b10 if fault == "iic-nack" else 0
    t0 = time.monotonic()
    video_addr = regmap.REGS_BASEADDR + regmap.register("VIDEO").offset
    lib.sys_init(ldata, len(ldata), rdata, len(rdata), CORE_PS, CAM_PS, CAM1_PS, 0, 12_345,
                 video_addr, UART_DIVISOR, nack)
    words_in = (C.c_uint32 * len(image))(*image)
    if lib.sys_load_ram(words_in, len(image)) != 0:
        lib.sys_final()
        raise RuntimeError("the firmware image does not fit the CPU's RAM")
    lib.sys_start()
    if fault == "camera-lost-left":
        pos, span = camera_lost_span(ldata)
        lib.sys_camera_stop(0, pos, span * CAM_PERIOD_PS)
    decoder = FrameDecoder()
    ended = []                      # (marker cycle, x, d) of frames not yet in a packet
    packets, exact_packets = [], []
    out_frames, current, aborted = [], [], 0
    total_records = 0
    stream_ps = max(len(ldata), len(rdata)) * CAM_PS
    # start-up (the XBee, the decoders: two report periods more when one does not answer; the
    # XBee's waits without a radio module, xbee.h: 3 responses and 4 guard times, 5 s with the
    # production values) + the streams + a report period more than the packets asked for
    guard_us = _macro(defines, "XBEE_GUARD_US", XBEE_GUARD_US)
    response_us = _macro(defines, "XBEE_RESPONSE_US", XBEE_RESPONSE_US)
    startup_ps = {"no-radio-module": (4 * guard_us + 5 * response_us) * 10**6 + 2 * REPORT_PS,
                  "iic-nack": 3 * REPORT_PS}.get(fault, REPORT_PS)
    end_ps = startup_ps + stream_ps + (min_packets + 1) * REPORT_PS
    last_frame_cycle = None
    frames_expected = frames - LOST_FIELDS if fault == "camera-lost-left" else frames
    queries = []                    # core cycles of the AT query frames on the TX pin
    lost_changes = []               # (core cycle, loss watch bits from then on)
    lost_bits = (C.c_uint8 * 1024)()
    cyc = (C.c_uint64 * 65536)()
    words = (C.c_uint32 * 65536)()
    txb = (C.c_uint8 * 65536)()
    frame_start_cycle = 0
    try:
        now = 0
        while now < end_ps:
            now += SLICE_PS
            lib.sys_run_until(now)
            while n := lib.sys_take_lost(cyc, lost_bits, len(lost_bits)):
                lost_changes += [(int(cyc[i]), int(lost_bits[i])) for i in range(n)]
            while n := lib.sys_take_records(cyc, words, len(words)):
                for i in range(n):
                    word = words[i]
                    if not word >> 31:
                        continue
                    total_records += 1
                    if word >> 29 & 1:              # abort marker
                        current, aborted = [], aborted + 1
                    elif word >> 28 & 1:            # end of frame
                        out_frames.append(current)
                        ended.append((cyc[i], [r[0] for r in current if not r[3]],
                                      [r[2] for r in current if not r[3]]))
                        current = []
                        if len(out_frames) == frames_expected:
                            last_frame_cycle = cyc[i]
                    else:
                        current.append((word & 0x3FF, word >> 10 & 0x3FF, word >> 20 & 0xFF,
                                        word >> 30 & 1))
            while n := lib.sys_take_tx(cyc, txb, len(txb)):
                for i in range(n):
                    b = txb[i]
                    if b == 0x7E:
                        frame_start_cycle = cyc[i]
                    for f in decoder.feed_frames(bytes([b])):
                        if f.api == API_AT_COMMAND:
                            queries.append(int(frame_start_cycle))
                        if fault != "no-radio-module" and (answer := _xbee_answer(f)):
                            lib.sys_send_rx(answer, len(answer))
                        if f.api == API_TX16 and f.packet is not None:
                            mine = [e for e in ended if e[0] < frame_start_cycle]
                            ended = [e for e in ended if e[0] >= frame_start_cycle]
                            pkt = f.packet
                            n = len(pkt.bands)
                            tops = [frame_top(x, d, pkt.width, n) for _c, x, d in mine]
                            expect = band_values(merge_tops(tops), DEFAULT_MIN_SUPPORT) \
                                if tops else [0] * n
                            packets.append((frame_start_cycle, pkt, len(mine)))
                            exact_packets.append(tuple(pkt.bands) == tuple(int(v) for v in expect))
            if last_frame_cycle is not None and len(packets) >= min_packets and \
                    any(c > last_frame_cycle for c, _p, _n in packets):
                break
        cycles = lib.sys_core_cycles()
        idle = lib.sys_idle_cycles()
        video_cycles = lib.sys_video_on_cycles()
        video_idle = lib.sys_video_on_idle()
        instructions = lib.sys_instructions()
        trapped = lib.sys_trap_cycles() > 0
        addressed = [lib.sys_decoder_addressed(k) for k in range(2)]
    finally:
        lib.sys_final()
    seconds = time.monotonic() - t0

    health = {k: 0 for k in ("frames", "pairs_ok", "mispaired", "drops", "matcher_errors",
                             "fifo_overflow")}
    cam_errors = [0, 0]
    flags = []
    per_packet = []
    for _c, pkt, _n in packets:
        counts = {k: getattr(pkt.health, k) for k in health}
        counts.update(cam_errors_left=pkt.health.cam_errors[0],
                      cam_errors_right=pkt.health.cam_errors[1])
        per_packet.append({k: v for k, v in counts.items() if v})
        for k in health:
            health[k] += getattr(pkt.health, k)
        cam_errors = [a + b for a, b in zip(cam_errors, pkt.health.cam_errors)]
        flags.append(pkt.health.flags)
    if fault is None or fault in ("iic-nack", "no-radio-module"):
        exact = out_frames[:frames] == want if fault is None else \
            len(out_frames) >= frames and out_frames[:frames] == want
    else:
        # the pairs the pipeline saw: (L0, R0), then from (L1+LOST, R1+LOST) on
        exact = frames_expected > FAULT_FIELD and out_frames == want[:frames_expected]
    if fault == "camera-lost-left":
        # the pairs the loss cost, and a packet that tells the left camera was lost
        counted = health["mispaired"] + health["drops"] + sum(cam_errors) > 0 and \
            any(lost_cameras(f) == ["left"] for f in flags)
    elif fault == "iic-nack":
        counted = addressed[1] > 0 and len(packets) > 0 and \
            all(f >> HEALTH_FLAGS["DECODER_FAULT"] & 1 for f in flags)
    elif fault == "no-radio-module":
        counted = len(packets) > 0 and all(f >> HEALTH_FLAGS["RADIO_FAULT"] & 1 for f in flags)
    else:
        counted = True
    rect_fault = any(f >> HEALTH_FLAGS["RECT_FAULT"] & 1 for f in flags)
    span = cycles - video_cycles if video_cycles else 0
    busy = span - (idle - video_idle)
    drained = total_records
    return {
        "bit_exact": bool(exact and counted), "fault": fault, "fault_counted": bool(counted),
        "width": w, "height": h, "timing": timing, "frames": health["frames"],
        "frames_out": len(out_frames), "pairs_ok": health["pairs_ok"],
        "mispaired": health["mispaired"], "drops": health["drops"],
        "errors": {"camera_left": cam_errors[0], "camera_right": cam_errors[1],
                   "matcher": health["matcher_errors"]},
        "fifo_overflow": health["fifo_overflow"], "aborted_frames": aborted,
        "records": sum(len(f) for f in out_frames), "golden_records": sum(len(f) for f in want[:frames_expected]),
        "record_fields": ["x", "y", "d", "floor"],
        "floor_points": sum(r[3] for f in out_frames for r in f),
        "floor_line": [floor.initial.slope, floor.initial.offset],
        "radio_packets": len(packets),
        "radio_exact": bool(packets) and all(exact_packets),
        "radio_bands": [list(p.bands) for _c, p, _n in packets],
        "radio_frames": [n for _c, _p, n in packets],
        "radio_cycles": [int(c) for c, _p, _n in packets],
        "radio_flags": flags,
        "radio_health": per_packet,
        "radio_queries": queries,
        "radio_cameras_lost": [lost_cameras(f) for f in flags],
        "camera_lost_changes": [list(c) for c in lost_changes],
        "rectified": rect is not None and bool(flags) and not rect_fault,
        "rect": None if rect is None else {"rect_fault": rect_fault, "need_span": rect.need_span,
                                           "build_span": rect.build_span,
                                           "cameras": rect.cameras},
        "decoders_addressed": [int(a) for a in addressed],
        "cpu": {"core": "picorv32",
                "configuration": "compact" if rect is None else rect.cpu_core,
                "image_bytes": sum(sections.values()), "sections": sections,
                "instructions": int(instructions),
                "busy_fraction": round(busy / span, 4) if span > 0 else None,
                "cycles_per_record": round(busy / drained, 1) if drained else None,
                "trapped": trapped, "defines": dict(defines or {})},
        "core_cycles": int(cycles), "sim_seconds": round(seconds, 1),
        "build_seconds": round(build_s, 1),
    }
