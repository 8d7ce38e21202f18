"""maskless: simulate, identify and control a soft-robot head positioner, as Drake diagrams.

The positioner is for mask-free head-and-neck radiotherapy.

The public API, one import away::

    import maskless

    scenario = maskless.load_scenario()  # the shipped defaults; or a YAML file over them
    run = maskless.simulate(scenario)
    run.metrics["tracking"]["p95_abs_error_mm"], run.signals["head_height_m"]
    run.write_mcap("out/run.mcap"), run.plot("out/run.png")

Every command of the ``maskless`` CLI is one call here: ``simulate`` (`maskless simulate`),
``excite`` (`maskless excite`), ``identify_record`` (`maskless identify`),
``analyze_operating_range``, ``analyze_stability`` and ``run_fault_matrix`` (`maskless
analyze`), ``run_sweep`` (`maskless montecarlo`) and ``run_workflow`` (`maskless workflow`).
Errors a user can cause are ``MasklessError``s that name the file, field or argument at fault.

Names are imported when first used, so ``import maskless`` stays cheap.
"""

from maskless.lazy_exports import lazy_exports

# Public name -> the module that defines it.
_EXPORTS = {
    # scenarios
    "Scenario": "maskless.diagrams.scenario",
    "load_scenario": "maskless.diagrams.scenario",
    "PneumaticPlant": "maskless.diagrams.scenario",
    "PaperPlant": "maskless.diagrams.scenario",
    "IdentifiedPlant": "maskless.diagrams.scenario",
    "OffsetFreeLqg": "maskless.diagrams.scenario",
    "PaperLqg": "maskless.diagrams.scenario",
    "KinectV1Config": "maskless.systems.sensing.depth_sensor",
    "KinectV2Config": "maskless.systems.sensing.depth_sensor",
    "CameraRenderingConfig": "maskless.systems.sensing.depth_sensor",
    "cameras_measured_by": "maskless.diagrams.scenario",
    "FaultConfig": "maskless.systems.fault_injection",
    # running
    "build_closed_loop": "maskless.diagrams.closed_loop",
    "simulate": "maskless.diagrams.simulation",
    "simulate_loop": "maskless.diagrams.simulation",
    "set_plant_parameters": "maskless.diagrams.closed_loop",
    "set_safety_reset": "maskless.diagrams.closed_loop",
    "SafetyConfig": "maskless.systems.control.safety_supervisor",
    "SWEPT_PARAMETERS": "maskless.systems.plant.pneumatic_plant",
    "SimulationRun": "maskless.diagrams.simulation",
    "excite": "maskless.diagrams.excitation_run",
    "ExcitationRequest": "maskless.diagrams.excitation_run",
    # populations
    "load_population": "maskless.diagrams.population",
    "population_preset_path": "maskless.diagrams.population",
    "MonteCarloConfig": "maskless.diagrams.population",
    "run_sweep": "maskless.diagrams.montecarlo",
    "SweepRequest": "maskless.diagrams.montecarlo",
    "read_trial_rows": "maskless.analysis.trial_table",
    # identification and design
    "identify": "maskless.diagrams.identification_run",
    "identify_record": "maskless.diagrams.identification_run",
    "IdentificationRequest": "maskless.diagrams.identification_run",
    "design_controller": "maskless.diagrams.controller_design",
    # analysis
    "analyze_operating_range": "maskless.diagrams.plant_analysis",
    "analyze_stability": "maskless.diagrams.plant_analysis",
    "StabilityRequest": "maskless.diagrams.plant_analysis",
    "run_workflow": "maskless.diagrams.workflow",
    "run_fault_matrix": "maskless.diagrams.fault_matrix",
    "FaultMatrixRequest": "maskless.diagrams.fault_matrix",
    # recordings
    "read_recording": "maskless.recording",
    "read_camera_frames": "maskless.recording",
    "CameraFrame": "maskless.camera_images",
    # errors
    "MasklessError": "maskless.errors",
    "ConfigError": "maskless.errors",
    "RecordError": "maskless.errors",
    "ModelError": "maskless.errors",
    "MissingFileError": "maskless.errors",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)
