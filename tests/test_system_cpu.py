"""``python -m sim system`` (``--cpu picorv32``, the default): the cross-compiled firmware on
the core inside the SoC, under Verilator, from BT.656 cameras to the radio UART's TX pin
(sim/system/cpu_run.py)."""
import contextlib
import io
import json

import pytest

from sim.system.command import main
from sim.system.cpu_run import LOST_FIELDS
from sim.system.run import CORE_PS
from station.wire import HEALTH_FLAGS, lost_cameras

#: a packet's health is read shortly before its first byte goes out: within this many core
#: cycles (5 ms; the report is built, its CRC taken, then its bytes sent between drains)
READ_BEFORE = 5 * 10**9 // CORE_PS
ENABLED = 1 << HEALTH_FLAGS["PIPELINE_ENABLED"]
CAMERA_LOST = 1 << HEALTH_FLAGS["CAMERA_LOST"]


def loss_in(changes, a, b):
    """The loss watch's bits (bit 0 left, bit 1 right) set at some time in core cycles
    (a, b], from ``camera_lost_changes`` ([cycle, bits from then on] at each change)."""
    now = 0
    seen = 0
    for cycle, bits in changes:
        if cycle <= a:
            now = bits
        elif cycle <= b:
            seen |= bits
    return now | seen


def reported_lost(flags):
    """The cameras a packet's flags report lost, as loss watch bits."""
    return sum(1 << k for k, side in enumerate(("left", "right")) if side in lost_cameras(flags))


def check_loss_reports(res):
    """Each packet reports lost (CAMERA_LOST, the side's LOCKED bit clear) every camera the
    SoC's loss watch showed lost at some time since the previous packet's health read, and no
    other: a side lost between the previous packet's first byte and READ_BEFORE before this
    one's must be reported, a side not lost from READ_BEFORE before the previous packet's first
    byte to this one's must not. Returns each packet's (reported, must, may) bits."""
    changes, out, prev = res["camera_lost_changes"], [], 0
    for cycle, flags in zip(res["radio_cycles"], res["radio_flags"]):
        got = reported_lost(flags)
        must = loss_in(changes, prev, cycle - READ_BEFORE)
        may = loss_in(changes, prev - READ_BEFORE, cycle)
        assert must & ~got == 0 and got & ~may == 0, (cycle, flags, must, may, changes)
        assert bool(flags & CAMERA_LOST) == (got != 0), (cycle, flags)
        out.append((got, must, may))
        prev = cycle
    return out


@pytest.fixture(scope="module")
def mixed():
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["--scene", "mixed", "--frames", "2"])        # the core by default
    return code, json.loads(buf.getvalue().strip().splitlines()[-1])


def test_records_and_packets_are_exact(mixed):
    code, res = mixed
    assert code == 0, res
    assert res["bit_exact"] and res["frames_out"] >= 2
    assert res["records"] == res["golden_records"] > 0
    assert res["radio_packets"] >= 1 and res["radio_exact"]
    assert res["fifo_overflow"] == 0 and res["drops"] == 0
    # the packets' summaries cover every frame (merged from the band summary unit)
    assert sum(res["radio_frames"]) >= 2
    # the video path enabled in the last packet's health; the decoders locked, or their
    # cameras lost since the previous packet (the streams end with the run's last field: two
    # field times later the loss watch fires) and so reported
    assert res["radio_flags"][-1] & ENABLED
    check_loss_reports(res)
    # the XBee model answered the firmware's queries and both decoders their configuration:
    # no packet reports a radio or decoder fault
    assert not any(f >> HEALTH_FLAGS["RADIO_FAULT"] & 1 for f in res["radio_flags"])
    assert not any(f >> HEALTH_FLAGS["DECODER_FAULT"] & 1 for f in res["radio_flags"])


def test_cpu_figures(mixed):
    _code, res = mixed
    cpu = res["cpu"]
    assert cpu["core"] == "picorv32" and not cpu["trapped"]
    assert 0 < cpu["image_bytes"] <= 8192 - 512
    assert cpu["instructions"] > 10_000
    assert 0 < cpu["busy_fraction"] < 1


def test_busy_scene_keeps_up():
    """The motorcycle scene's rows bring records faster than the core could read them one by
    one: the band summary unit takes them all (0 lost, no FIFO overflow) and every packet is
    the merge of the frames it covers."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["--cpu", "picorv32", "--scene", "motorcycle", "--frames", "3"])
    res = json.loads(buf.getvalue().strip().splitlines()[-1])
    assert code == 0, res
    assert res["bit_exact"] and res["records"] == res["golden_records"] > 6000
    assert res["fifo_overflow"] == 0 and res["drops"] == 0
    assert res["radio_packets"] >= 1 and res["radio_exact"] and sum(res["radio_frames"]) >= 3
    assert res["cpu"]["busy_fraction"] <= 0.5
    # the image flags by the motorcycle camera's floor line (its generated table), not the
    # nominal rig's, whose line lies above many of its obstacle points
    from sim.flows.floor_table import scene_line
    line = scene_line("motorcycle")
    assert res["floor_line"] == [line.slope, line.offset]
    assert 0 < res["floor_points"] < res["records"] // 50


@pytest.mark.parametrize("argv", [
    ["--cpu", "picorv32", "--width", "64", "--height", "16"],
    ["--cpu", "picorv32", "--timing", "short"],
    ["--width", "64", "--height", "16"],                 # the core is the default
    ["--fault", "noise-left"],
    ["--cpu", "host", "--fault", "iic-nack"],
    ["--cpu", "host", "--fault", "no-radio-module"],
    ["--cpu", "picorv32", "--fault", "noise-left"],
    ["--cpu", "picorv32", "--fault", "camera-lost-left", "--frames", "5"],
    ["--right-lead", "5"],
    ["--cpu", "riscv"],
    ["--cpu", ""],
])
def test_bad_combinations_are_usage_errors(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:")


def test_decoder_not_answering_is_bounded_and_the_other_runs():
    """--fault iic-nack: the right decoder never answers its address. The firmware retries it
    for two report periods, then starts the video path without it: the packets go on, their
    sequence unbroken, every one reports the decoder's fault (DECODER_FAULT, health bit 6),
    and the frames are exact."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["--cpu", "picorv32", "--scene", "mixed", "--frames", "5", "--fault",
                     "iic-nack"])
    res = json.loads(buf.getvalue().strip().splitlines()[-1])
    assert code == 0, res
    assert res["bit_exact"] and res["fault_counted"] and res["frames_out"] == 5
    assert res["radio_packets"] >= 2 and res["radio_exact"]
    flags = res["radio_flags"]
    assert flags[0] & 0b100 == 0 and flags[-1] & ENABLED
    # both streams locked once the video path runs, unless lost (the run's end) and so reported
    reports = check_loss_reports(res)
    assert all(f & 0b111 == 0b111 for f, (_g, _m, may) in zip(flags, reports)
               if f & ENABLED and not may)
    assert all(f >> HEALTH_FLAGS["DECODER_FAULT"] & 1 for f in flags)
    assert not any(f >> HEALTH_FLAGS["RADIO_FAULT"] & 1 for f in flags)
    # bounded: the start-up's attempt and the two tries, an address byte each (the next
    # retry is 20 periods away); the left decoder took its whole configuration
    left, right = res["decoders_addressed"]
    assert right == 3 and left > 20


def test_decoder_not_answering_is_configured_again_every_retry_period():
    """--fault iic-nack on a variant of the image that configures a failed decoder again
    every report period (DECODER_RETRY_PERIODS 1 for 20, main.c takes it with #ifndef): after
    the start-up's tries, one attempt (an address byte the decoder does not acknowledge) at
    the start of each period; the packets still come one a period, each with DECODER_FAULT."""
    from sim.system.cpu_run import REPORT_PS, run_cpu_system
    from sim.system.run import CORE_PS, scene_pair
    ms = 10**9 // CORE_PS                                   # core cycles a millisecond
    defines = {"DECODER_RETRY_PERIODS": "1u"}
    res = run_cpu_system(*scene_pair("mixed", 720, 240), frames=2, fault="iic-nack",
                         defines=defines, min_packets=4)
    assert res["bit_exact"] and res["fault_counted"] and res["radio_exact"], res
    assert res["cpu"]["defines"] == defines and not res["cpu"]["trapped"]
    flags = res["radio_flags"]
    assert len(flags) >= 4 and all(f >> HEALTH_FLAGS["DECODER_FAULT"] & 1 for f in flags)
    # the video path runs meanwhile: both streams locked unless lost (the run's end)
    reports = check_loss_reports(res)
    assert all(f & ENABLED for f in flags[2:])
    assert all(f & 0b111 == 0b111 for f, (_g, _m, may) in zip(flags[2:], reports[2:]) if not may)
    # the start-up's attempt and one in each period begun: the periods of the packets
    # decoded, and the one in progress when the run ended
    assert res["decoders_addressed"][1] == len(flags) + 2
    period = REPORT_PS // CORE_PS
    packets = res["radio_cycles"]
    assert all(abs(b - a - period) < 18 * ms for a, b in zip(packets, packets[1:]))


def test_camera_lost_counts_the_loss_and_the_pipeline_resumes_exact():
    """--fault camera-lost-left: the left decoder gets no byte for LOST_FIELDS fields from the
    end of field 0. The right camera's fields of that time have no partner and the pairing
    drops them, one by one: the packets' health counts them (drops), no FIFO overflows, the
    packets go on, and the pipeline resumes with (L5, R5) bit-exact.

    The loss is reported: every packet tells the cameras the SoC's loss watch showed lost
    since the previous packet (check_loss_reports). The left camera is lost for about one
    field time, from two field times after its last start to its return, well inside one
    report period: a packet reports it although the camera is back when its health is read
    (the firmware gathers the live bit between reports), the next packet inside the streams
    reports both cameras locked again. 14 fields: the streams last past that packet, whose
    period the end of the streams (both cameras lost two field times after their last
    start) does not reach."""
    frames = 14
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["--scene", "mixed", "--frames", str(frames), "--fault", "camera-lost-left"])
    res = json.loads(buf.getvalue().strip().splitlines()[-1])
    assert code == 0, res
    assert res["bit_exact"] and res["fault_counted"] and res["radio_exact"]
    assert res["frames_out"] == frames - LOST_FIELDS
    assert res["records"] == res["golden_records"] > 0
    assert res["drops"] == LOST_FIELDS and res["mispaired"] == 0
    assert res["fifo_overflow"] == 0 and res["errors"] == {"camera_left": 0, "camera_right": 0,
                                                           "matcher": 0}
    # a packet tells the loss, and the packets after it carry the resumed pairs
    assert res["radio_packets"] >= 2
    assert sum(h.get("drops", 0) for h in res["radio_health"]) == LOST_FIELDS
    assert res["radio_health"][-1].get("drops", 0) == 0 and res["radio_health"][-1]["pairs_ok"] > 0
    # the loss watch saw the left camera lost, then back (later both lost: the streams' end)
    changes = res["camera_lost_changes"]
    assert [bits for _c, bits in changes[:2]] == [0b01, 0b00]
    reports = check_loss_reports(res)
    flags, cycles = res["radio_flags"], res["radio_cycles"]
    left = [i for i, f in enumerate(flags) if res["radio_cameras_lost"][i] == ["left"]]
    assert left and left == list(range(left[0], left[-1] + 1)) and len(left) <= 2
    assert all(lost_cameras(f) == ["left"] for f in (flags[i] for i in left))
    assert all(f & 1 << HEALTH_FLAGS["RIGHT_LOCKED"] for f in (flags[i] for i in left))
    # sticky: the last packet that tells it was read with the left camera back
    back = changes[1][0]
    assert back < cycles[left[-1]] - READ_BEFORE and reported_lost(flags[left[-1]]) == 0b01
    # cleared after: the next packet, inside the streams, is clean (no camera lost)
    after = left[-1] + 1
    assert after < len(flags) and reports[after][2] == 0
    assert flags[after] & 0b111 == 0b111 and not flags[after] & CAMERA_LOST


#: The waits of the image the no-radio-module test runs (firmware/Makefile FIRMWARE_DEFS).
SHORT_RADIO_WAITS = {"XBEE_GUARD_US": "10000u", "XBEE_RESPONSE_US": "2000u",
                     "RADIO_RETRY_PERIODS": "1u"}


def test_missing_radio_module_is_bounded_retried_and_reported():
    """--fault no-radio-module on the core: nothing answers the XBee. The start-up
    configuration gives up after its bounded waits, the pipeline runs, every packet carries
    RADIO_FAULT (health bit 5), and the firmware queries the module again (an API-mode AT
    query on the TX pin) right before each report, one retry period apart.

    This runs a variant of the image with shortened waits (SHORT_RADIO_WAITS: XBee guard time
    10 ms and response time 2 ms for 1.1 s and 200 ms, a retry every report period for every
    20): with the production values the configuration alone takes 5 s of simulated time and
    the retries come 2 s apart, far too long a simulation for the suite (``python -m sim system
    --fault no-radio-module`` runs the production image). The code is the production code;
    only those constants differ (main.c and xbee.h take them with #ifndef)."""
    from sim.system.cpu_run import REPORT_PS, run_cpu_system
    from sim.system.run import CORE_PS, scene_pair
    ms = 10**9 // CORE_PS                                   # core cycles a millisecond
    res = run_cpu_system(*scene_pair("mixed", 720, 240), frames=2, fault="no-radio-module",
                         defines=SHORT_RADIO_WAITS, min_packets=2)
    assert res["bit_exact"] and res["fault_counted"] and res["radio_exact"], res
    assert res["records"] == res["golden_records"] > 0 and not res["cpu"]["trapped"]
    assert res["cpu"]["defines"] == SHORT_RADIO_WAITS
    flags = res["radio_flags"]
    assert len(flags) >= 2 and all(f >> HEALTH_FLAGS["RADIO_FAULT"] & 1 for f in flags)
    # video on in every packet; both decoders locked unless their cameras were lost (after
    # the streams end) and so reported
    reports = check_loss_reports(res)
    assert all(f & ENABLED for f in flags)
    assert all(f & 0b111 == 0b111 for f, (_g, _m, may) in zip(flags, reports) if not may)
    # bounded: the configuration's waits (3 responses, 4 guard times), the rest of the start-up
    # (the decoders' configuration over IIC, "+++" at 9600 baud: under 40 ms), then one report
    # period and at most a frame's wait (17 ms) for the first report; then one a period
    period = REPORT_PS // CORE_PS
    packets, queries = res["radio_cycles"], res["radio_queries"]
    assert packets[0] < (3 * 2 + 4 * 10 + 40 + 17) * ms + period
    assert all(abs(b - a - period) < 18 * ms for a, b in zip(packets, packets[1:]))
    # the start-up's query, then a retry right before each report
    assert queries[0] < 1 * ms and len(queries) == 1 + len(packets)
    assert all(0 < p - q < 2 * ms for q, p in zip(queries[1:], packets))
