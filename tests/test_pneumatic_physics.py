"""Pneumatic physics: ISO 6358 flow against its closed form, valve opening, spool, head force."""

import math

import numpy as np
import pytest

from maskless.systems.plant.pneumatic_physics import (
    head_force_n,
    mass_flow_kg_s,
    spool_rate,
    subsonic_flow_factor,
    two_way_mass_flow_kg_s,
    valve_opening,
)
from maskless.systems.plant.pneumatic_plant import load_pneumatic_parameters

B, LAMINAR = 0.3, 0.999


@pytest.fixture(scope="module")
def p():
    return load_pneumatic_parameters()


def iso_6358_elliptic(r, b):
    """ISO 6358-1 subsonic flow factor, written from the standard."""
    return math.sqrt(1.0 - ((r - b) / (1.0 - b)) ** 2)


@pytest.mark.parametrize("ratio", [0.0, 0.1, 0.25, 0.3])
def test_choked_flow_factor_is_one(ratio):
    assert subsonic_flow_factor(ratio, B, LAMINAR) == pytest.approx(1.0, abs=1e-15)


@pytest.mark.parametrize("ratio", [0.35, 0.5, 0.7, 0.9, 0.99, 0.998])
def test_subsonic_flow_factor_is_the_elliptic_law(ratio):
    assert subsonic_flow_factor(ratio, B, LAMINAR) == pytest.approx(
        iso_6358_elliptic(ratio, B), rel=1e-12
    )


def test_laminar_segment_is_linear_to_zero_and_continuous():
    at_laminar = iso_6358_elliptic(LAMINAR, B)
    assert subsonic_flow_factor(LAMINAR, B, LAMINAR) == pytest.approx(at_laminar, rel=1e-12)
    # Continuity from both sides of the laminar ratio.
    for side in (LAMINAR - 1e-9, LAMINAR + 1e-9):
        assert subsonic_flow_factor(side, B, LAMINAR) == pytest.approx(at_laminar, rel=1e-6)
    assert subsonic_flow_factor(1.0, B, LAMINAR) == pytest.approx(0.0, abs=1e-15)
    for r in (0.9992, 0.9995, 0.9999):
        expected = at_laminar * (1.0 - r) / (1.0 - LAMINAR)
        assert subsonic_flow_factor(r, B, LAMINAR) == pytest.approx(expected, rel=1e-9)
    # Linear: equal slopes on two sub-intervals of the segment.
    r = np.array([0.9991, 0.9994, 0.9997])
    phi = np.array([subsonic_flow_factor(x, B, LAMINAR) for x in r])
    assert (phi[1] - phi[0]) / 0.0003 == pytest.approx((phi[2] - phi[1]) / 0.0003, rel=1e-6)


@pytest.mark.parametrize(
    "p_up, p_down", [(300e3, 40e3), (300e3, 150e3), (200e3, 199.95e3), (101.325e3, 60e3)]
)
def test_mass_flow_closed_form(p, p_up, p_down):
    conductance, b = 8.2e-10, 0.3
    r = p_down / p_up
    if r <= b:
        phi = 1.0
    elif r <= p.laminar_pressure_ratio:
        phi = iso_6358_elliptic(r, b)
    else:
        phi = (
            iso_6358_elliptic(p.laminar_pressure_ratio, b)
            * (1 - r)
            / (1 - p.laminar_pressure_ratio)
        )
    expected = (
        conductance
        * p.reference_density_kg_m3
        * math.sqrt(p.reference_temperature_k / p.air_temperature_k)
        * p_up
        * phi
    )
    assert mass_flow_kg_s(conductance, b, p_up, p_down, p) == pytest.approx(expected, rel=1e-12)
    # Backwards (downstream higher) a one-way valve passes nothing.
    assert mass_flow_kg_s(conductance, b, p_down, p_up, p) == 0.0


@pytest.mark.parametrize(
    "p_1, p_2", [(101325.0, 90e3), (150e3, 101325.0), (101325.0, 101300.0), (40e3, 300e3)]
)
def test_two_way_mass_flow_is_antisymmetric(p, p_1, p_2):
    forward = two_way_mass_flow_kg_s(6.7e-9, 0.3, p_1, p_2, p)
    backward = two_way_mass_flow_kg_s(6.7e-9, 0.3, p_2, p_1, p)
    assert forward == pytest.approx(-backward, rel=1e-14)
    assert np.sign(forward) == np.sign(p_1 - p_2)
    assert two_way_mass_flow_kg_s(6.7e-9, 0.3, p_1, p_1, p) == 0.0


@pytest.mark.parametrize(
    "current, expected",
    [(0.0, 0.0), (0.059, 0.0), (0.060, 0.0), (0.0825, 0.5 * 0.0225 / 0.0525), (0.165, 1.0)],
)
def test_valve_opening_piecewise_linear(p, current, expected):
    assert valve_opening(current, p.inlet) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("current", [0.1125, 0.08, 0.15])
def test_valve_opening_linear_between(p, current):
    assert valve_opening(current, p.inlet) == pytest.approx((current - 0.060) / 0.105, rel=1e-12)


@pytest.mark.parametrize("current", [0.166, 0.2, 1.0])
def test_valve_opening_saturates(p, current):
    assert valve_opening(current, p.outlet) == 1.0


def test_spool_rate_dead_zone(p):
    valve = p.inlet
    half_width = 0.5 * 0.05 * (0.165 - 0.060)  # hysteresis fraction of the span, halved
    tau = 0.02
    spool = 0.1
    for error in (0.0, 0.5 * half_width, -0.99 * half_width):
        assert spool_rate(spool + error, spool, valve) == 0.0
    for error in (2 * half_width, 0.03, -0.01, -3 * half_width):
        expected = (error - math.copysign(half_width, error)) / tau
        assert spool_rate(spool + error, spool, valve) == pytest.approx(expected, rel=1e-12)


def test_head_force_equilibrium_at_zero_gauge(p):
    assert p.unloaded_lift_m == pytest.approx(4.75 * 9.80665 / 4000.0, rel=1e-15)
    # The nominal head rests at zero lift on the unpressurised bladder.
    assert head_force_n(0.0, 0.0, 0.0, p) == pytest.approx(0.0, abs=1e-12)
    # Off the rest point the fabric pushes back with its stiffness, pressure adds A p.
    assert head_force_n(0.0, 0.002, 0.0, p) == pytest.approx(-4000.0 * 0.002, rel=1e-12)
    assert head_force_n(1000.0, 0.0, 0.0, p) == pytest.approx(0.015 * 1000.0, rel=1e-12)
    assert head_force_n(0.0, 0.0, 0.01, p) == pytest.approx(-225.0 * 0.01, rel=1e-12)
    # Travel limit: below min lift the limit spring adds k_limit * depth.
    depth = 0.001
    expected = 4000.0 * (0.008 + depth) + 20000.0 * depth
    assert head_force_n(0.0, -0.008 - depth, 0.0, p) == pytest.approx(expected, rel=1e-12)
