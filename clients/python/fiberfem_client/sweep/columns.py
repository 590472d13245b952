"""The names a sweep file and the table share: error measures, their columns, the cost
columns (docs/sweeps.md). No imports: the sweep file is checked without loading the
numerical libraries."""

# Error measure (sweep file name) -> the table columns it fills.
ERROR_MEASURES = {
    "probe": ("probe_err", "probe_err_m", "final_err"),
    "l2": ("l2_err",),
    "volume": ("volume_err",),
    "ef": ("ef_err_pp",),
    "phase": ("phase_err_ms",),
    "settled": ("settled_err", "settled_err_m"),
    # The closed-loop circulation's last complete beat (the report's circulation.beats).
    "pv_loop": ("pv_loop_err", "edv_err", "esv_err", "lv_ef_err_pp"),
    "stroke_volume": ("stroke_volume_err",),
    "peak_lv_pressure": ("peak_lv_pressure_err",),
}
# The measures of a sweep with a reference and no `errors` key (the circulation's are asked for).
DEFAULT_ERRORS = ("probe", "l2", "volume", "ef", "phase", "settled")
# Cost columns a sweep may rank by (smaller is cheaper).
COST_MEASURES = ("engine_s_per_sim_s", "wall_s_per_sim_s", "wall_s", "peak_rss_mb")
# The column each error measure is ranked by (Pareto front, goals, plots).
ERROR_COLUMN = {"probe": "probe_err", "l2": "l2_err", "volume": "volume_err", "ef": "ef_err_abs_pp",
                "phase": "phase_err_abs_ms", "settled": "settled_err", "pv_loop": "pv_loop_err",
                "stroke_volume": "stroke_volume_err", "peak_lv_pressure": "peak_lv_pressure_err"}
