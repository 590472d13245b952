"""The fiberfem DDS types (idl/mesh.idl, idl/control.idl, idl/status.idl,
idl/circulation.idl) for the
`cyclonedds` Python binding. Same names, members, order, keys and extensibility as the
IDL: keep them in step (tests/idl/python_types_check.py compares them with the IDL member by
member; tests/service/serve_test.cpp checks the two talk)."""

from dataclasses import dataclass

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.annotations import appendable, key
from cyclonedds.idl.types import float32, float64, int16, int32, sequence, uint32, uint64


@dataclass
@appendable
class MeshTopology(IdlStruct, typename="fiberfem::MeshTopology"):
    run_id: str
    key("run_id")
    scene_name: str
    scene_hash: str
    replay: bool
    num_nodes: uint32
    num_elements: uint32
    rest_positions: sequence[float32]
    tets: sequence[int32]
    triangles: sequence[int32]
    triangle_elements: sequence[int32]
    element_regions: sequence[int16]
    region_names: sequence[str]
    fibers: sequence[float32]
    state_nodes: sequence[int32]
    fixed_nodes: sequence[int32]


@dataclass
@appendable
class MeshState(IdlStruct, typename="fiberfem::MeshState"):
    run_id: str
    key("run_id")
    frame: uint64
    time_s: float64
    parameter_version: uint32
    positions: sequence[float32]
    activation: sequence[float32]


@dataclass
@appendable
class Command(IdlStruct, typename="fiberfem::Command"):
    run_id: str
    key("run_id")
    command_id: str
    key("command_id")
    client_id: str
    kind: str
    args: str


@dataclass
@appendable
class CommandAck(IdlStruct, typename="fiberfem::CommandAck"):
    run_id: str
    key("run_id")
    command_id: str
    client_id: str
    accepted: bool
    reason: str
    frame: uint64
    parameter_version: uint32


@dataclass
@appendable
class ServiceStatus(IdlStruct, typename="fiberfem::ServiceStatus"):
    run_id: str
    key("run_id")
    scene_name: str
    host: str
    pid: int32
    state: str
    mode: str
    replay: bool
    frame: uint64
    time_s: float64
    frames_per_second: float64
    real_time_factor: float64
    step_ms: float64
    rotations_ms: float64
    assembly_ms: float64
    solve_ms: float64
    publish_ms: float64
    record_ms: float64
    solver_iterations: int32
    solver_residual: float64
    inverted_elements: int32
    kinetic_energy_j: float64
    elastic_energy_j: float64
    recovered_steps: uint32
    failed_steps: uint32
    last_message: str
    parameter_version: uint32
    heart_rate_bpm: float64
    peak_tension_pa: float64
    dt_s: float64
    recording: str
    recorded_frames: uint64


@dataclass
@appendable
class CirculationState(IdlStruct, typename="fiberfem::CirculationState"):
    """A run's lumped circulation at one frame (SI units; docs/dds.md, docs/circulation.md)."""
    run_id: str
    key("run_id")
    frame: uint64
    time_s: float64
    la_pressure_pa: float64
    la_volume_m3: float64
    systemic_arterial_pressure_pa: float64
    systemic_arterial_flow_m3_s: float64
    mitral_flow_m3_s: float64
    lv_pressure_pa: float64
    lv_volume_m3: float64
    systemic_venous_pressure_pa: float64
    systemic_venous_flow_m3_s: float64
    aortic_flow_m3_s: float64
    ra_pressure_pa: float64
    ra_volume_m3: float64
    pulmonary_arterial_pressure_pa: float64
    pulmonary_arterial_flow_m3_s: float64
    tricuspid_flow_m3_s: float64
    rv_pressure_pa: float64
    rv_volume_m3: float64
    pulmonary_venous_pressure_pa: float64
    pulmonary_venous_flow_m3_s: float64
    pulmonary_valve_flow_m3_s: float64
    pressure_iterations: int32
    blood_volume_m3: float64
    beat: int32
    beat_start_s: float64
    lv_end_diastolic_volume_m3: float64
    lv_end_systolic_volume_m3: float64
    lv_stroke_volume_m3: float64
    lv_ejection_fraction: float64
    lv_peak_pressure_pa: float64
    lv_end_diastolic_pressure_pa: float64
    rv_end_diastolic_volume_m3: float64
    rv_end_systolic_volume_m3: float64
    rv_stroke_volume_m3: float64
    rv_ejection_fraction: float64
    rv_peak_pressure_pa: float64
    rv_end_diastolic_pressure_pa: float64
    systemic_arterial_max_pa: float64
    systemic_arterial_min_pa: float64
    pulmonary_arterial_max_pa: float64
    pulmonary_arterial_min_pa: float64
