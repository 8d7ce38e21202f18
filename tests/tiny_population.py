"""A small population for the Monte Carlo tests: the standard one, in 14 simulated seconds."""

from pathlib import Path

from maskless.diagrams.population import load_population

TINY_POPULATION = """
trials: 6
seed: 3
controllers: [offset-free-lqg, paper-lqg]
positioning_time_s: 1.0
step_time_s: 4.0
worst_traces: 2
scenario_presets: [paper_camera_noise]
population:
  head_mass_kg: {low: 3.5, high: 6.5}
  stiffness_factor: {low: 0.7, high: 1.3}
  leak_factor: {low: 0.7, high: 1.3}
  inlet_conductance_factor: {low: 0.7, high: 1.3}
  outlet_conductance_factor: {low: 0.7, high: 1.3}
  supply_gauge_pressure_pa: {low: 172369.0, high: 241317.0}
  step_size_m: {low: 0.002, high: 0.010}
  lift_margin_m: 0.0015
  inlet_authority_fraction: 0.9
scenario:
  duration_s: 14.0
  metrics: {evaluation_delay_s: 6.0}
  patient_motion: {enabled: true, shift_rate_per_s: 0.2}
"""


def tiny_population_file(folder: Path, text: str = TINY_POPULATION) -> Path:
    path = folder / "tiny.yaml"
    path.write_text(text)
    return path


def tiny_population(folder: Path, **changes):
    config = load_population(tiny_population_file(folder))
    for name, value in changes.items():
        setattr(config, name, value)
    return config
