"""The WebSocket messages between `fiberfem web` and its page (spec: docs/web.md).

Text messages are JSON objects with a "type"; the one binary message is a frame: a 48-byte
little-endian header, then the surface positions (3 float32 per vertex, metres) and the
field (1 float32 per vertex)."""

import json
import math
import struct

import numpy as np

from .surface import FIELDS

FRAME_MAGIC = b"FFW1"
# magic, vertices, frame, time_s, source ms, bridge ms, parameter version, field index
FRAME_HEADER = struct.Struct("<4sIdddd II")
assert FRAME_HEADER.size == 48

# Commands a page may send, per kind of run: the service's and replay's own (docs/commands.md,
# docs/replay.md); everything else is refused by the bridge before it reaches the bus.
LIVE_KINDS = ("pause", "resume", "step", "reset", "set_contraction", "set_gravity", "clear_force")
REPLAY_KINDS = ("pause", "resume", "step", "seek", "set_rate", "loop")
MAX_MESSAGE_BYTES = 65536


class ProtocolError(ValueError):
    """A message from the page that is not one of docs/web.md's: the reason is shown on the page."""


def encode_frame(frame: int, time_s: float, source_ms: float, bridge_ms: float, parameter_version: int,
                 field: str, positions: np.ndarray, values: np.ndarray) -> bytes:
    header = FRAME_HEADER.pack(FRAME_MAGIC, positions.shape[0], float(frame), time_s, source_ms, bridge_ms,
                               parameter_version, FIELDS.index(field))
    return header + np.ascontiguousarray(positions, dtype="<f4").tobytes() + np.ascontiguousarray(values, dtype="<f4").tobytes()


def _number_list(value, name: str, length: int) -> list:
    if (not isinstance(value, list) or len(value) != length
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)):
        raise ProtocolError(f"'{name}' must be a list of {length} finite numbers")
    return [float(v) for v in value]


def _request_id(msg: dict):
    rid = msg.get("id")
    if not isinstance(rid, int) or isinstance(rid, bool) or not 0 <= rid < 2**53:
        raise ProtocolError("'id' must be a whole number in [0, 2^53)")
    return rid


def parse(text) -> dict:
    """Checks one message from the page; raises ProtocolError naming what is wrong."""
    if not isinstance(text, str):
        raise ProtocolError("the page sends text messages (JSON objects) only")
    try:
        msg = json.loads(text)
    except ValueError as e:
        raise ProtocolError(f"not JSON: {e}") from None
    if not isinstance(msg, dict) or not isinstance(msg.get("type"), str):
        raise ProtocolError("a message is a JSON object with a string 'type'")
    kind = msg["type"]
    allowed = {"ready": set(), "watch": {"run", "field"}, "command": {"id", "kind", "args"},
               "press": {"id", "point", "force"}, "release": {"id"}}
    if kind not in allowed:
        raise ProtocolError(f"unknown message type '{kind}' (types: {', '.join(allowed)})")
    extra = set(msg) - allowed[kind] - {"type"}
    if extra:
        raise ProtocolError(f"'{kind}' takes no '{sorted(extra)[0]}'")
    if kind == "watch":
        if not isinstance(msg.get("run"), str) or not msg["run"]:
            raise ProtocolError("'watch' needs 'run', a run id")
        if msg.get("field") not in FIELDS:
            raise ProtocolError(f"'field' must be one of {', '.join(FIELDS)}")
    elif kind == "command":
        _request_id(msg)
        if not isinstance(msg.get("kind"), str):
            raise ProtocolError("'command' needs 'kind', a string")
        if not isinstance(msg.get("args", {}), dict):
            raise ProtocolError("'args' must be a JSON object")
        msg.setdefault("args", {})
    elif kind == "press":
        _request_id(msg)
        msg["point"] = _number_list(msg.get("point"), "point", 3)
        msg["force"] = _number_list(msg.get("force"), "force", 3)
    elif kind == "release":
        _request_id(msg)
    return msg


def _json_number(v):
    """JSON has no NaN or infinity: those are shown as unknown (null)."""
    return None if isinstance(v, float) and not math.isfinite(v) else v


MMHG_PA = 133.322387415  # Pa per mmHg
ML_M3 = 1e6              # mL per m^3


def circulation_message(run: str, samples, restart: bool) -> dict:
    """A run's circulation samples as the page draws them: the loop's points (frame, time s,
    LV volume mL, LV pressure mmHg, RV volume mL, RV pressure mmHg), oldest first; `restart`
    when the page should drop the points it has. "now" holds the newest sample's pressures
    (mmHg), volumes (mL) and flows (mL/s), "beat" its last complete beat's figures."""
    points = [[c.frame, c.time_s, c.lv_volume_m3 * ML_M3, c.lv_pressure_pa / MMHG_PA,
               c.rv_volume_m3 * ML_M3, c.rv_pressure_pa / MMHG_PA] for c in samples]
    c = samples[-1]
    now = {"frame": c.frame, "time_s": c.time_s,
           "lv_pressure_mmhg": c.lv_pressure_pa / MMHG_PA, "lv_volume_ml": c.lv_volume_m3 * ML_M3,
           "rv_pressure_mmhg": c.rv_pressure_pa / MMHG_PA, "rv_volume_ml": c.rv_volume_m3 * ML_M3,
           "aortic_pressure_mmhg": c.systemic_arterial_pressure_pa / MMHG_PA,
           "pulmonary_arterial_pressure_mmhg": c.pulmonary_arterial_pressure_pa / MMHG_PA,
           "aortic_flow_ml_s": c.aortic_flow_m3_s * ML_M3, "mitral_flow_ml_s": c.mitral_flow_m3_s * ML_M3}
    beat = None
    if c.beat > 0:
        beat = {"beat": c.beat,
                "lv_stroke_volume_ml": _json_number(c.lv_stroke_volume_m3 * ML_M3), "lv_ejection_fraction": _json_number(c.lv_ejection_fraction),
                "lv_peak_pressure_mmhg": _json_number(c.lv_peak_pressure_pa / MMHG_PA),
                "rv_stroke_volume_ml": _json_number(c.rv_stroke_volume_m3 * ML_M3), "rv_ejection_fraction": _json_number(c.rv_ejection_fraction),
                "aortic_max_mmhg": _json_number(c.systemic_arterial_max_pa / MMHG_PA),
                "aortic_min_mmhg": _json_number(c.systemic_arterial_min_pa / MMHG_PA)}
    return {"type": "circulation", "run": run, "restart": restart, "points": points, "now": now, "beat": beat}


def status_message(s, beat: float) -> dict:
    """A run's ServiceStatus as the page shows it."""
    keys = ("run_id", "scene_name", "host", "state", "mode", "replay", "frame", "time_s", "frames_per_second",
            "real_time_factor", "step_ms", "solver_iterations", "solver_residual", "parameter_version",
            "heart_rate_bpm", "peak_tension_pa", "dt_s", "recording", "recorded_frames", "last_message",
            "failed_steps", "recovered_steps")
    out = {k: _json_number(getattr(s, k)) for k in keys}
    out.update(type="status", beat=_json_number(beat))
    return out
