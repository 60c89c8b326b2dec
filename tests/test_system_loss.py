"""A camera lost in the middle of a full NTSC field (sim/system/run.py, 720 x 240): the SoC's
loss watch (hdl/camera_port.py LossWatch) flags the left camera while the pair (L1, R1) is
open and the pairing abandons that pair (golden/pairing.py rule 5), so the pipeline resumes
with the first pair that starts after the camera's return, bit-exact."""
import json
import subprocess
import sys

import pytest

from sim.system.run import LOST_FIELDS


@pytest.mark.slow
def test_camera_lost_mid_field_at_full_size_resumes_at_the_first_pair_after_the_return():
    frames = 8
    r = subprocess.run([sys.executable, "-m", "sim", "system", "--cpu", "host",
                        "--fault", "camera-lost-left-mid", "--frames", str(frames)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    res = json.loads(r.stdout.strip().splitlines()[-1])
    assert (res["width"], res["height"], res["timing"]) == (720, 240, "ntsc")
    assert res["bit_exact"] and res["fault_counted"], res
    # (L0, R0), the abandoned (L1, R1), then every pair from the first after the return
    assert res["mispaired"] == 1 and res["aborted_frames"] == 0
    assert res["frames_out"] == res["pairs_ok"] + 1 == frames - LOST_FIELDS
