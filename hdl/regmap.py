"""The pipeline's register map, defined once.

Everything else is derived from the tables in this module:

- ``hdl/regs.py`` elaborates the register block RTL from :data:`REGISTERS`;
- ``sim/flows/gen_regs.py`` writes ``firmware/include/stereo_regs.h`` (the firmware's only view of
  the map) and ``docs/registers.md``; ``tests/test_regs.py`` fails when the committed files
  differ from a fresh generation.

Bus: the MicroBlaze MCS I/O bus (Xilinx PG116, "I/O Bus"), 32-bit data, byte addresses. A
transfer starts with a one-cycle ``IO_Addr_Strobe`` together with ``IO_Read_Strobe`` or
``IO_Write_Strobe``; ``IO_Address``, ``IO_Write_Data`` and ``IO_Byte_Enable`` are valid in that
cycle only. The addressed peripheral answers with a one-cycle ``IO_Ready`` (and
``IO_Read_Data`` for a read) any number of cycles later; the CPU stalls until then. Only one
transfer is outstanding at a time. Peripherals that do not decode the address keep
``IO_Ready`` low and ``IO_Read_Data`` zero, so the SoC ORs the answers of all peripherals.

Register kinds (``Register.kind``):

- ``rw``: parameter register; every field drives an output of the block; writes honour the
  byte enables; reset value from the fields.
- ``ro``: status register; fields come from inputs of the block; writes are ignored.
- ``pulse``: write-one-to-pulse: a field written with 1 drives its output high for one cycle;
  reads return 0.
- ``fifo``: reading pops one record from the result FIFO (an empty FIFO reads 0, valid = 0);
  the record's second half waits in RESULT_EXT (``ro``, the block's own) until the next read.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

from golden.floor import FloorLine, FloorParams, OFFSET_BITS, SLOPE_BITS, TOL_BITS, TOL_SHIFT_BITS
from golden.matcher import CONFIDENCE_MAX, DISPARITY_BITS, DISPARITY_SPAN, SUBPIXEL_BITS
from golden.pipeline import default_params

from .matcher_start import MARGIN_BITS, SEARCH_MARGIN

__all__ = ["Field", "Register", "REGISTERS", "REGS_BASEADDR", "IIC_BASEADDR", "REGS_WINDOW",
           "IIC_WINDOW", "ID_MAGIC", "MAP_VERSION", "MAX_WIDTH", "MAX_HEIGHT", "DISPARITY_SPAN",
           "register", "field", "parameter_fields", "config_fields", "param_value",
           "status_fields", "tables", "encode_params", "RECT_BASEADDR", "RECT_WINDOW",
           "RECT_LEFT_BASEADDR",
           "RECT_MAP_OFFSET", "RECT_REGISTERS", "rect_register", "rect_map_check"]

#: MCS I/O bus addresses: the I/O bus occupies 0xC0000000..0xFFFFFFFF on the MCS.
REGS_BASEADDR = 0xC000_0000
REGS_WINDOW = 0x100           #: bytes decoded by the register block
IIC_BASEADDR = 0xC001_0000
IIC_WINDOW = 0x200            #: bytes decoded by the IIC controller (AXI IIC layout)

ID_MAGIC = 0x5354             #: "ST"
MAP_VERSION = 13

#: Elaboration limits the map is sized for (one definition): the RESULT register's x, y and d
#: fields and the MATCH register's d_min / d_max hold every value up to them. A pipeline
#: elaborated beyond them does not fit the map (hdl/regs.py ``check_result_limits``).
MAX_WIDTH = 1024              #: widest frame (x < MAX_WIDTH)
MAX_HEIGHT = 1024             #: tallest frame (y < MAX_HEIGHT)
_XB = (MAX_WIDTH - 1).bit_length()
_YB = (MAX_HEIGHT - 1).bit_length()
_DB = DISPARITY_BITS          #: disparities 0 .. golden.matcher.MAX_DISPARITY
_D16B = _DB + SUBPIXEL_BITS   #: subpixel disparities d16 = 16 d + offset, 1/16 px
_CB = CONFIDENCE_MAX.bit_length()     #: confidence 0 .. golden.matcher.CONFIDENCE_MAX

#: Reset values of the parameters are the golden models' defaults (golden/ground.py,
#: golden/sobel.py, golden/matcher.py), with the ground reference area at the bottom centre of
#: the frame the cameras deliver: one NTSC field of the ADV7180 decoders, 720 x 240
#: (firmware/include/app.h APP_FIELD_WIDTH / APP_FIELD_HEIGHT).
REF_WIDTH, REF_HEIGHT = 720, 240
_P = default_params(REF_WIDTH, REF_HEIGHT)      # reset values: the default pipeline
_G = _P.frontend.ground
_S = _P.frontend.sobel
_M = _P.matcher
_F = _P.frontend.free
_FL = FloorParams()
#: The floor line FLOOR_LINE resets to, which the firmware writes at start-up (the rig's): the
#: project's nominal rig (``sim.scenes.rendered.Rig``: 0.12 m baseline, optical centres 0.35 m
#: above the floor, pitched 12 degrees down, focal length 600 px at 752 columns) seen by the
#: ADV7180 cameras, one field of a REF_WIDTH x 2 REF_HEIGHT frame: the field's row v is the
#: frame's row 2 v, so its line is the frame's with twice the slope (the same as a rig of twice
#: the baseline with half the focal length and half the principal row, ``FloorLine.from_rig``).
RIG_FLOOR_LINE = FloorLine.from_rig(focal_px=600.0 * REF_WIDTH / 752 / 2, baseline_m=2 * 0.12,
                                    height_m=0.35, pitch_deg=12.0, cy=(2 * REF_HEIGHT - 1) / 4)


@dataclass(frozen=True)
class Field:
    """One register field. A run-time parameter (``rw``) also names, once for every user, what
    it binds together: ``param``, the golden parameter it holds (a path into
    :class:`golden.pipeline.PipelineParams`; ``a|b``: ``a``, or ``b`` where ``a`` is None;
    ``path=choice0,choice1``: the index of the value in the choices) and ``port``, the
    :class:`hdl.pipeline.StereoPipeline` input it drives (a path; None: the SoC's own control).
    The SoC's connections (``hdl/soc.py``), the simulators' port values (``sim/config.py``), the
    firmware's ``pipeline_config_t`` and its accessors (``STEREO_CONFIG_FIELDS`` in the
    generated ``stereo_regs.h``) and the co-simulation's ctypes mirror all follow this table."""
    name: str
    lsb: int
    width: int
    reset: int = 0
    doc: str = ""
    param: str | None = None
    port: str | None = None

    @property
    def mask(self) -> int:
        return ((1 << self.width) - 1) << self.lsb


@dataclass(frozen=True)
class Register:
    name: str
    offset: int
    kind: str          # "rw", "ro", "pulse", "fifo"
    doc: str
    fields: tuple[Field, ...]
    #: ``ro`` registers only: the name of the table (a memory outside the block) the register
    #: is read from, or None: a status input. The registers of one table are consecutive
    #: words; word ``k`` of the run is entry ``k`` (hdl/regs.py ``<table>_index`` /
    #: ``<table>_word``).
    table: str | None = None

    @property
    def reset(self) -> int:
        """Value read after reset (status inputs assumed 0, ID constant)."""
        return sum(f.reset << f.lsb for f in self.fields) if self.kind in ("rw", "ro") else 0


F = Field


def GF(name, lsb, width, doc):
    """A ground model field: its reset value, golden parameter (``frontend.ground.<name>``) and
    port (``ground.<name>``) all follow from the name."""
    return F(name, lsb, width, int(getattr(_G, name)), doc, param=f"frontend.ground.{name}",
             port=f"ground.{name}")


REGISTERS: tuple[Register, ...] = (
    Register("ID", 0x00, "ro", "Identification: constant, lets the firmware check the bitstream.", (
        F("version", 0, 16, MAP_VERSION, "register map version"),
        F("magic", 16, 16, ID_MAGIC, "0x5354 (\"ST\")"),
    )),
    Register("CTRL", 0x04, "pulse", "Control pulses (write 1 to act; reads 0).", (
        F("clear_errors", 0, 1, 0, "clear every sticky error counter"),
        F("flush_results", 1, 1, 0, "empty the result FIFO and clear its overflow count"),
        F("restart_video", 2, 1, 0, "reset the video path (camera ports, pairing, pipeline): "
                                    "it resumes at the next field start of both cameras"),
    )),
    Register("GROUND", 0x08, "rw", "Ground classifier (golden/ground.py): mode and band width.", (
        GF("mode", 0, 2, "0 off (every pixel is an obstacle), 1 luminance, 2 hue"),
        GF("k", 4, 4, "half-width of the ground band, in JND units"),
        GF("jnd_hue", 8, 4, "just-noticeable hue difference, hue units (0..191 circle)"),
        GF("jnd_luma", 12, 4, "just-noticeable luminance difference, luma codes"),
        GF("s_min", 16, 8, "minimum saturation for a reliable hue; greyer pixels use the luminance band"),
    )),
    Register("GROUND_REF_POS", 0x0C, "rw", "Reference area (learned as ground): top-left corner. "
             f"Reset: bottom centre of a {REF_WIDTH}x{REF_HEIGHT} frame.", (
        GF("ref_x", 0, 11, "first column of the reference area"),
        GF("ref_y", 16, 11, "first row of the reference area"),
    )),
    Register("GROUND_REF_SIZE", 0x10, "rw", "Reference area: size.", (
        GF("ref_w", 0, 11, "width in pixels"),
        GF("ref_h", 16, 11, "height in rows"),
    )),
    Register("GROUND_INIT", 0x14, "rw", "Ground band centres used before the first frame is learned.", (
        GF("hue_centre0", 0, 8, "initial hue centre, 0..191"),
        GF("luma_centre0", 8, 8, "initial luminance centre"),
    )),
    Register("SOBEL", 0x18, "rw", "Vertical-edge detector (golden/sobel.py).", (
        F("edge_threshold", 0, 11, _S.threshold, "minimum |Gx| of an edge pixel",
          param="frontend.sobel.threshold", port="threshold"),
        F("ratio", 16, 4, _S.ratio, "dominance, units of 1/4: edge only if 4|Gx| >= ratio |Gy|",
          param="frontend.sobel.ratio", port="ratio"),
        F("nms", 24, 1, int(_S.nms), "1: keep only horizontal local maxima of |Gx| (non-maximum suppression)",
          param="frontend.sobel.nms", port="nms"),
    )),
    Register("SOBEL_RIGHT", 0x20, "rw", "Right camera's edge threshold: its edges only select "
             "the candidates of the matcher, so it is lower than the left's (golden/pipeline.py).", (
        F("right_threshold", 0, 11, _P.right_threshold, "minimum |Gx| of a right-image edge pixel",
          param="right_threshold|frontend.sobel.threshold", port="right_threshold"),
    )),
    Register("VIDEO", 0x2C, "rw", "Video path (hdl/soc.py): cameras, pairing, pipeline.", (
        F("video_enable", 0, 1, 0, "1: the video path runs; 0: it is held in reset (set it once "
                                   "both decoders report lock)"),
    )),
    Register("MATCH", 0x1C, "rw", "Stereo matcher (golden/matcher.py, hdl/matcher.py).", (
        F("d_min", 0, _DB, _M.d_min, "smallest disparity tried",
          param="matcher.d_min", port="d_min"),
        F("d_max", 8, _DB, _M.d_max, f"largest disparity tried (d_min <= d_max <= d_min + "
                                     f"{DISPARITY_SPAN - 1}: a window of at most "
                                     f"{DISPARITY_SPAN} disparities)",
          param="matcher.d_max", port="d_max"),
        F("uniqueness", 16, 8, _M.uniqueness, "margin u in 1/256 units: reject the best d if a "
                                               "candidate d' (|d'-d| > 1) has window costs "
                                               "256 C(d') <= (256 + u) C(d)",
          param="matcher.uniqueness", port="uniqueness"),
        F("candidate_mode", 24, 1, 0 if _M.mode == "adaptive" else 1,
          "0 adaptive (only right-image edge columns), 1 full range",
          param="matcher.mode=adaptive,full", port="mode_full"),
        F("widen", 25, 2, int(_M.widen), "candidate spread: a right-image edge within widen "
                                         "pixels of x - d makes d a candidate (0..2; 3 acts as 2)",
          param="matcher.widen", port="widen"),
        F("camera_mode_drop", 27, 1, 0, "1: camera inputs that cannot stall: the matcher drops "
                                        "(and counts) edges it has no time for (hdl/matcher.py drop_mode)", port="drop_mode"),
        F("sign", 28, 1, int(_M.sign == "any"), "which right-image edges make candidates: 0 "
                                                "those of the left edge's Gx sign, 1 either sign",
          param="matcher.sign=same,any", port="sign_any"),
    )),
    Register("GROUND_CLIP", 0x24, "rw", "Ground model v2: luminance clip levels (golden/ground.py).", (
        GF("y_lo", 0, 8, "lowest luma code with a reliable hue; darker luma bins are never ground"),
        GF("y_hi", 8, 8, "highest luma code with a reliable hue; brighter luma bins are never ground"),
    )),
    Register("GROUND_SET", 0x28, "rw", "Ground model v2: histogram sets and learning.", (
        GF("frac", 0, 8, "a bin is ground when its count smoothed over +-1 JND reaches "
                         "support x frac / 1024 (support: the histogram's total)"),
        GF("min_support", 8, 16, "fewest reliable hue samples (pixels) in the model "
                                 "for hue classification; fewer: luminance fallback"),
        GF("blend_shift", 24, 3, "model' = model + (new - model) / 2^blend_shift "
                                 "(0: the last frame only)"),
        GF("hue_and_luma", 28, 1, "1: a pixel with a reliable hue also needs its "
                                  "luminance in the luma set"),
        GF("fallback_shift", 29, 3, "in hue fallback the luma set's threshold "
                                    "is the luma threshold >> fallback_shift"),
    )),
    # Free space (golden/freespace.py, hdl/freespace.py): configuration and each camera's
    # last frame, 16 bands of 16 bits, two bands per word.
    Register("FREE_CFG", 0x30, "rw", "Free space per column band (golden/freespace.py), both "
             f"cameras. Reset: 16 bands across a {REF_WIDTH}-column frame. Kept but unused in "
             "a build without free space.", (
        F("band_w", 0, 11, _F.band_w, "free space: columns per band, 16 bands from x = 0",
          param="frontend.free.band_w", port="band_w"),
        F("run_r", 16, 8, _F.run_r, "free space: rows an obstacle run needs (a row of a band is "
                                    "obstacle when more than half its pixels are), at least 1",
          param="frontend.free.run_r", port="run_r"),
    )),
    *(Register(f"FREE_{side.upper()}_{k}", base + 4 * k, "ro",
               f"{side.capitalize()} camera, last frame: free-space rows of bands {2 * k} and "
               f"{2 * k + 1} (the image row of the lowest obstacle run, scanning up from the "
               "bottom; 0xFFFF: none). Updated in the 16 cycles after each frame; 0xFFFF "
               "after reset (the SoC's table, hdl/freespace.py FreeSpaceTable). Reads 0 in a "
               "build without free space (SystemSoC's free_space, off by default).", (
                   F("even", 0, 16, 0, f"band {2 * k}: row, or 0xFFFF"),
                   F("odd", 16, 16, 0, f"band {2 * k + 1}: row, or 0xFFFF"),
               ), table=f"free_{side}")
      for side, base in (("left", 0x90), ("right", 0xB0)) for k in range(8)),
    Register("FRAME_COUNT", 0x40, "ro", "Frames completed by the matcher since reset.", (
        F("frames", 0, 32, 0, "frame counter (wraps)"),
    )),
    Register("ERR_LEFT", 0x44, "ro", "Left front end sticky counters (saturating; CTRL.clear_errors).", (
        F("errors", 0, 16, 0, "malformed-stream errors"),
        F("dropped", 16, 16, 0, "pixels dropped on overflow"),
    )),
    Register("ERR_RIGHT", 0x48, "ro", "Right front end sticky counters.", (
        F("errors", 0, 16, 0, "malformed-stream errors"),
        F("dropped", 16, 16, 0, "pixels dropped on overflow"),
    )),
    Register("ERR_MATCH", 0x4C, "ro", "Matcher sticky counters.", (
        F("errors", 0, 16, 0, "malformed-stream errors"),
        F("dropped", 16, 16, 0, "frames or lines dropped"),
    )),
    Register("STAT_EDGES", 0x50, "ro", "Last frame: left vertical-edge pixels.", (
        F("count", 0, 32, 0, "edge pixels"),
    )),
    Register("STAT_EVALUATIONS", 0x54, "ro", "Last frame: window-cost evaluations.", (
        F("count", 0, 32, 0, "window comparisons"),
    )),
    Register("STAT_MATCHES", 0x58, "ro", "Last frame: matches emitted.", (
        F("count", 0, 32, 0, "(x, y, d) records"),
    )),
    Register("STAT_REJECTS", 0x5C, "ro", "Last frame: candidates rejected by the uniqueness test.", (
        F("count", 0, 32, 0, "rejections"),
    )),
    Register("STAT_DROPS", 0x60, "ro", "Last frame: edge pixels not matched for lack of time.", (
        F("count", 0, 32, 0, "drops"),
    )),
    # Health block (hdl/soc.py, hdl/camera_port.py, hdl/pairing.py): what the firmware reports.
    Register("HEALTH_CAMERA", 0x64, "ro", "BT.656 decoders: malformed lines (saturating; "
             "cleared by CTRL.restart_video).", (
        F("left_errors", 0, 16, 0, "left camera"),
        F("right_errors", 16, 16, 0, "right camera"),
    )),
    Register("HEALTH_OVERFLOW", 0x68, "ro", "Camera FIFOs: pixels dropped because the core did "
             "not keep up (a frame's whole tail from the first; saturating).", (
        F("left", 0, 16, 0, "left camera"),
        F("right", 16, 16, 0, "right camera"),
    )),
    Register("HEALTH_PAIRS", 0x6C, "ro", "Frame pairing (golden/pairing.py); 16-bit counts "
             "that wrap: take differences.", (
        F("pairs_ok", 0, 16, 0, "pairs of two well-formed frames forwarded"),
        F("mispaired", 16, 16, 0, "pairs abandoned because a frame was malformed"),
    )),
    Register("HEALTH_DROPS", 0x70, "ro", "Frames lost before the pipeline, and matcher errors.", (
        F("frames", 0, 16, 0, "frames without partner discarded by the pairing (wraps)"),
        F("match_errors", 16, 16, 0, "matcher malformed-stream errors (saturating)"),
    )),
    Register("HEALTH_STATUS", 0x74, "ro", "Video path state.", (
        F("left_locked", 0, 1, 0, "left decoder stream: a field edge seen since the video "
                                  "reset (stays set while the camera is lost: left_lost)"),
        F("right_locked", 1, 1, 0, "right decoder stream: as left_locked"),
        F("enabled", 2, 1, 0, "VIDEO.video_enable as applied"),
        F("pairing", 3, 1, 0, "a pair is being forwarded"),
        F("left_lost", 4, 1, 0, "left camera: no field start for over two NTSC field times "
                                "(hdl/camera_port.py LossWatch; cleared by its next field "
                                "start and by the video reset). Live, not sticky: the "
                                "firmware gathers it between reports (app_watch_health) "
                                "into the radio health flag CAMERA_LOST"),
        F("right_lost", 5, 1, 0, "as left_lost, right camera"),
    )),
    Register("GROUND_STATUS", 0x78, "ro", "Ground model status of the current frame, per camera.", (
        F("left_learned", 0, 1, 0, "1: classified by learned sets (0: the default bands)"),
        F("left_hue_fallback", 1, 1, 0, "1: too few reliable hues: classified by luminance"),
        F("right_learned", 2, 1, 0, "as left_learned, right camera"),
        F("right_hue_fallback", 3, 1, 0, "as left_hue_fallback, right camera"),
    )),
    Register("HEALTH_SKEW", 0x7C, "ro", "Capture skew (hdl/skew.py, golden/skew.py): the time "
             "between the two cameras' field starts, measured for every pair of starts at the "
             "camera ports (a start pairs with the other camera's next start within "
             "8,000 us, under half an NTSC field: the nearest; cleared by "
             "CTRL.restart_video).", (
        F("us", 0, 16, 0, "right field start minus left field start of the last pair, whole "
                          "microseconds, two's complement (negative: the right camera was first)"),
        F("pairs", 16, 16, 0, "pairs of field starts measured (wraps): a new us since the last "
                              "read when it moved"),
    )),
    # The floor decision (golden/floor.py, hdl/floor.py FloorFlag on the records before the
    # result FIFO and the band summary): the flag's tolerance and the v-disparity line, which
    # the CPU writes (the rig's line, or the one it learned from the records). The unit loads
    # both registers in the cycle after each frame's end-of-frame record passes it.
    Register("FLOOR", 0xD0, "rw", "Floor flag of the records (golden/floor.py floor_flags): "
             "a record is a floor point when d16 <= line16(y) + tol + (max(line16(y), 0) >> "
             "tol_shift), except an obstacle's foot under an obstacle record of its disparity "
             "in the row above (golden/floor.py keep_feet). Loaded at each frame's end: a "
             "write applies from the frame after the one in progress. The matcher's search start (floor_search, floor_margin) takes "
             "FLOOR_LINE with them when a frame starts (hdl/matcher_start.py).", (
        F("floor_enable", 0, 1, 0, "1: flag floor points by FLOOR_LINE; 0: no record is one"),
        F("floor_search", 1, 1, 0, "1: the matcher tries at row y only d with 16 d >= "
                                   "line16(y) - floor_margin (golden/floor.py search_start16); "
                                   "0: the whole window"),
        F("floor_tol", 8, TOL_BITS, _FL.tol, "tolerance above the line, 1/16 px"),
        F("floor_tol_shift", 16, TOL_SHIFT_BITS, _FL.tol_shift,
          "the tolerance grows by max(line16, 0) >> floor_tol_shift"),
        F("floor_margin", 24, MARGIN_BITS, SEARCH_MARGIN,
          "how far under the line the search starts, 1/16 px"),
    )),
    Register("FLOOR_LINE", 0xD4, "rw", "The v-disparity floor line (golden/floor.py FloorLine): "
             "line16(y) = (slope y + offset) >> 4 in 1/16 px. One word, so a frame never loads "
             "half a line. Reset: the nominal rig's line in one field of a "
             f"{REF_WIDTH}x{2 * REF_HEIGHT} camera (hdl/regmap.py RIG_FLOOR_LINE).", (
        F("floor_slope", 0, SLOPE_BITS, RIG_FLOOR_LINE.slope, "1/256 px of disparity per row"),
        F("floor_offset", SLOPE_BITS, OFFSET_BITS, RIG_FLOOR_LINE.offset % (1 << OFFSET_BITS),
          "1/256 px, two's complement"),
    )),
    Register("RESULT", 0x80, "fifo", "Result FIFO head; a read pops one whole record, whose "
             "second half (d16, conf) RESULT_EXT then shows.", (
        F("x", 0, _XB, 0, "column of the left edge pixel"),
        F("y", _XB, _YB, 0, "row"),
        F("d", _XB + _YB, _DB, 0, "disparity"),
        F("eof", _XB + _YB + _DB, 1, 0, "1: an end-of-frame marker, no match (x, y, d = 0): "
                                        "the records since the previous marker are one "
                                        "frame's (SystemSoC)"),
        F("abort", _XB + _YB + _DB + 1, 1, 0, "with eof: that frame was cut by "
                                              "CTRL.restart_video or VIDEO.video_enable = 0: "
                                              "discard its records"),
        F("floor", _XB + _YB + _DB + 2, 1, 0, "1: a floor point (hdl/floor.py, by the line "
                                              "of FLOOR and FLOOR_LINE): not an obstacle"),
        F("valid", 31, 1, 0, "1: a record; 0: no whole record was waiting (the FIFO was empty, "
                             "or the read came in the cycle right after a RESULT read, while "
                             "the FIFO steps over that record's second half: read again)"),
    )),
    Register("RESULT_LEVEL", 0x84, "ro", "Result FIFO state.", (
        F("level", 0, 16, 0, "records waiting"),
        F("overflow", 16, 16, 0, "records lost because the FIFO was full (saturating; cleared by "
                                  "CTRL.flush_results or CTRL.clear_errors)"),
    )),
    Register("RESULT_EXT", 0x88, "ro", "Second half of the record the last RESULT read popped. "
             "Read order: RESULT, then RESULT_EXT, before the next RESULT read (that read "
             "replaces it). 0 after a RESULT read with valid = 0, and for eof/abort markers.", (
        F("d16", 0, _D16B, 0, "subpixel disparity in 1/16 px: 16 d + offset, offset -8..8 "
                              "(golden/matcher.py step 6; 16 d from a matcher without that "
                              "step, cost sad)"),
        F("conf", _D16B, _CB, 0, f"confidence of the match, 0..{CONFIDENCE_MAX} "
                                 "(golden/matcher.py step 6; 0 without that step)"),
    )),
)


def register(name: str, registers=REGISTERS) -> Register:
    """The register ``name`` of ``registers`` (the main window's by default)."""
    for reg in registers:
        if reg.name == name:
            return reg
    raise KeyError(name)


def field(reg_name: str, field_name: str) -> Field:
    for f in register(reg_name).fields:
        if f.name == field_name:
            return f
    raise KeyError(f"{reg_name}.{field_name}")


def parameter_fields():
    """(register, field) of every run-time parameter, in map order."""
    return [(r, f) for r in REGISTERS if r.kind == "rw" for f in r.fields]


def config_fields():
    """(register, field) of every pipeline parameter (a field with a ``port``), in map order:
    the members of the firmware's ``pipeline_config_t``."""
    return [(r, f) for r, f in parameter_fields() if f.port is not None]


def param_value(params, f):
    """The value field ``f`` holds for golden ``params`` (a
    :class:`golden.pipeline.PipelineParams`, or any object with the attributes its ``param``
    path names), as an integer; its reset value for a field of no golden parameter, and None
    when ``params`` lacks the path (e.g. a front end's parameters have no matcher)."""
    if f.param is None:
        return f.reset
    path, _, choices = f.param.partition("=")
    for alternative in path.split("|"):
        obj = params
        for name in alternative.split("."):
            obj = getattr(obj, name, None)
        if obj is not None:
            return choices.split(",").index(obj) if choices else int(obj)
    return None


def status_fields():
    """(register, field) of every status input (the block's own RESULT_LEVEL, RESULT_EXT and
    ID, and the registers read from tables, excluded)."""
    return [(r, f) for r in REGISTERS if r.kind == "ro"
            and r.name not in ("ID", "RESULT_LEVEL", "RESULT_EXT")
            and r.table is None for f in r.fields]


def tables():
    """``{table name: its registers in address order}`` (see :attr:`Register.table`)."""
    runs = {}
    for r in REGISTERS:
        if r.table is not None:
            runs.setdefault(r.table, []).append(r)
    return {name: sorted(regs, key=lambda r: r.offset) for name, regs in runs.items()}


def _check_layout(registers, window):
    """Every register word-aligned inside ``window`` bytes, at its own offset, of a known kind;
    its fields inside 32 bits, not overlapping, their resets within their widths."""
    offsets = set()
    for reg in registers:
        if reg.offset % 4 or not 0 <= reg.offset < window or reg.offset in offsets:
            raise ValueError(f"bad offset for {reg.name}")
        if reg.kind not in ("rw", "ro", "pulse", "fifo"):
            raise ValueError(f"bad kind for {reg.name}")
        offsets.add(reg.offset)
        used = 0
        for f in reg.fields:
            if f.lsb + f.width > 32 or used & f.mask or not 0 <= f.reset < (1 << f.width):
                raise ValueError(f"bad field {reg.name}.{f.name}")
            used |= f.mask


def _check():
    _check_layout(REGISTERS, REGS_WINDOW)
    for reg in REGISTERS:
        if reg.table is not None and reg.kind != "ro":
            raise ValueError(f"{reg.name}: only ro registers are read from a table")
    for name, run in tables().items():
        if [r.offset for r in run] != list(range(run[0].offset, run[0].offset + 4 * len(run), 4)):
            raise ValueError(f"table {name}: its registers must be consecutive words")


_check()


def encode_params(ground=None, sobel=None, matcher=None, *, right_threshold=None,
                  camera_mode_drop=0, free=None) -> dict:
    """Register values (name -> 32-bit value) for golden parameter dataclasses (``free``: a
    :class:`golden.freespace.FreeSpaceParams`); None = the register's reset value
    (``right_threshold`` None: the left's threshold when ``sobel`` is given). What the
    firmware writes for the same settings."""
    params = SimpleNamespace(frontend=SimpleNamespace(ground=ground, sobel=sobel, free=free),
                             matcher=matcher, right_threshold=right_threshold)
    values = {}
    for reg in REGISTERS:
        if reg.kind != "rw":
            continue
        v = 0
        for f in reg.fields:
            x = camera_mode_drop if f.name == "camera_mode_drop" else param_value(params, f)
            x = f.reset if x is None else x
            if not 0 <= x < (1 << f.width):
                raise ValueError(f"{reg.name}.{f.name} = {x} does not fit {f.width} bits")
            v |= x << f.lsb
        values[reg.name] = v
    return values


# Per-band obstacle summary (hdl/bands.py, golden/bands.py): a peripheral of its own on the I/O
# bus, beside the register block (whose window is full), the IIC master (0xC0010000), the UART
# (0xC0020000), the CPU's timer (0xC0030000) and the motion controller's mailbox (0xC0040000).
BANDS_BASEADDR = 0xC005_0000
BANDS_WINDOW = 0x400          #: bytes decoded by the band summary
#: Byte offsets in the band summary's window (meanings: hdl/bands.py).
#: CFG (rw): width bits 10..0 (reset 720), n_bands bits 22..16 (reset 32).
#: STATUS (ro): frames bits 15..0 (published frames, wraps), built bit 16 (the band table
#: matches CFG and CFG is valid), bad_cfg bit 17, lost bit 18 (the published frame lost records).
#: DROPS (ro): records dropped bits 15..0 (saturating), aborted frames bits 31..16 (wraps).
#: RECORDS (rw): fifo bit 0 (reset 0): in the SoC with its CPU inside (hdl/soc.py), 1 sends the
#: records to the result FIFO too (RESULT); 0 spares the FIFO (it neither fills nor overflows).
#: TOP (ro): from 0x100, ceil(slots / 4) words per band, band 0 first: the published frame's
#: largest disparities of the band, the largest in bits 7..0, then 15..8, 23..16, 31..24.
BANDS_REGS = {"CFG": 0x000, "STATUS": 0x004, "DROPS": 0x008, "RECORDS": 0x00C, "TOP": 0x100}
#: (kind, reset, description) of each register of the band summary's window, for
#: docs/registers.md (sim/flows/gen_regs.py).
BANDS_DOCS = {
    "CFG": ("rw", 720 | 32 << 16, "width bits 10..0 (columns, n_bands..1024), n_bands bits "
            "22..16 (1..64). A write refills the band table (width cycles, STATUS.built 0 "
            "meanwhile; records then are dropped): write it between frames."),
    "STATUS": ("ro", 0, "frames bits 15..0 (frames published, wraps), built bit 16 (the band "
               "table matches CFG), bad_cfg bit 17 (CFG out of range: every record dropped), "
               "lost bit 18 (the published frame lost records)."),
    "DROPS": ("ro", 0, "records dropped bits 15..0 (saturating), aborted frames bits 31..16 "
              "(wraps)."),
    "RECORDS": ("rw", 0, "fifo bit 0: in the SoC with its CPU inside, 1 sends the records to "
                "the result FIFO (RESULT) as well; 0 spares it (it neither fills nor "
                "overflows). A write leaves the band table alone."),
    "TOP": ("ro", 0, "from 0x100, one word per band (band 0 first) of the published frame: its "
            "four largest disparities, the largest in bits 7..0, then 15..8, 23..16, 31..24 "
            "(0: fewer matches). Read STATUS, the words, STATUS again: the frame is whole when "
            "both frame counts agree."),
}


# Right-camera rectifier (hdl/rectify.py, golden/rectify.py): a peripheral of its own on the I/O
# bus, present only in a build with the rectifier (StereoSoC / SystemSoC ``rectify=``); a build
# without it leaves its window unanswered (reads 0: RECT_INFO.span = 0, no rectifier).
RECT_BASEADDR = 0xC006_0000
RECT_WINDOW = 0x8000          #: bytes decoded by the rectifier
#: The left camera's rectifier (SystemSoC / StereoSoC ``rectify_left=``, for calibrations that
#: rectify both cameras): the same registers in the next window.
RECT_LEFT_BASEADDR = RECT_BASEADDR + RECT_WINDOW
#: Byte offset of the map words: node (j, k) at RECT_MAP_OFFSET + 4 (j * 2^stride_log2 + k),
#: write-only, word dx | dy << 10 (golden.rectify.node_words), 4096 words at most.
RECT_MAP_OFFSET = 0x4000

RECT_REGISTERS: tuple[Register, ...] = (
    Register("RECT_CTRL", 0x00, "rw", "Rectifier control; change it between frames (the "
             "rectifier samples it at each right frame's start).", (
        F("enable", 0, 1, 0, "1: the right image is rectified through the map; 0: it passes "
                             "unchanged"),
        F("lo", 8, 6, 0, "first buffered source row relative to the output row, two's "
                         "complement, -span..0 (golden.rectify.row_window)"),
    )),
    Register("RECT_VALID_POS", 0x04, "rw", "Rectified valid region of the right image (every "
             "pixel inside has its source inside the image): top-left corner, as the "
             "calibration gives it; kept for the firmware's report.", (
        F("x", 0, 11, 0, "first column"),
        F("y", 16, 11, 0, "first row"),
    )),
    Register("RECT_VALID_SIZE", 0x08, "rw", "Rectified valid region: size (0: not set).", (
        F("w", 0, 11, 0, "width in pixels"),
        F("h", 16, 11, 0, "height in rows"),
    )),
    Register("RECT_INFO", 0x0C, "ro", "What this build's rectifier takes (0: no rectifier).", (
        F("span", 0, 6, 0, "line buffer rows less one: the largest vertical warp across the "
                           "image is span - 1 rows"),
        F("stride_log2", 8, 4, 0, "log2 of the map's row stride in words"),
        F("node_rows", 12, 6, 0, "map node rows the build holds"),
        F("linear", 18, 1, 0, "1: bilinear in both directions; 0: nearest column"),
        F("preloaded", 19, 1, 0, "1: the map memory was initialised in the bitstream"),
    )),
    Register("RECT_MAP_CHECK", 0x10, "ro", "XOR of every map word the memory received, each "
             "as word | node address << 20: the bitstream's initial map (when preloaded) and "
             "every write since. The firmware compares it with its table's.", (
        F("check", 0, 32, 0, "XOR of word | address << 20"),
    )),
)


_check_layout(RECT_REGISTERS, RECT_MAP_OFFSET)


def rect_register(name: str) -> Register:
    return register(name, RECT_REGISTERS)


def rect_map_check(words) -> int:
    """RECT_MAP_CHECK after the map memory received ``words`` (``(address, word)`` pairs,
    :func:`golden.rectify.node_words`) from zero."""
    check = 0
    for addr, word in words:
        check ^= word | addr << 20
    return check
