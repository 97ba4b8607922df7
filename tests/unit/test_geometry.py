"""Gear geometry, ISO tooth stiffness and the dimensional -> dimensionless conversion."""

import math

import pytest

from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.physical.geometry import GearGeometry, iso_flexibility, iso_single_stiffness


def test_iso_flexibility_hand_computed():
    # q' = 0.04723 + 0.15551 / 18 + 0.25791 / 36 (beta = 0, x1 = x2 = 0)
    q = 0.04723 + 0.15551 / 18 + 0.25791 / 36
    assert q == pytest.approx(0.0630336, abs=1e-7)
    assert iso_flexibility(18, 36) == pytest.approx(q, rel=1e-12)
    # c' = C_M / q' = 0.8 / 0.0630336 = 12.6916 N/(mm um)
    assert iso_single_stiffness(18, 36) == pytest.approx(12.6916, rel=1e-5)
    assert iso_single_stiffness(18, 36, c_m=1.0) == pytest.approx(15.8645, rel=1e-5)
    # profile shift terms enter with the ISO coefficients
    assert iso_flexibility(18, 36, x1=0.5) == pytest.approx(
        q - 0.00635 * 0.5 - 0.11654 * 0.5 / 18 + 0.00529 * 0.25, rel=1e-12)


def test_mesh_stiffness_is_1p5_single_tooth_times_width():
    g = GearGeometry(face_width_mm=20.0)
    ks = 12.69164 * 20.0 * 1e6  # N/(mm um) * mm -> N/um -> N/m
    assert g.single_tooth_stiffness == pytest.approx(ks, rel=1e-5)
    assert g.mesh_stiffness == pytest.approx(1.5 * ks, rel=1e-5)
    assert GearGeometry(face_width_mm=40.0).mesh_stiffness == pytest.approx(
        2 * g.mesh_stiffness)


def test_geometry_derived_values():
    g = GearGeometry()
    assert g.pitch_radius_p == pytest.approx(0.036)
    assert g.pitch_radius_g == pytest.approx(0.072)
    assert 1.4 < g.contact_ratio < 1.8
    me = g.inertia_p * g.inertia_g / (g.inertia_p * 0.072**2 + g.inertia_g * 0.036**2)
    assert g.equivalent_mass == pytest.approx(me)
    assert g.natural_frequency == pytest.approx(math.sqrt(g.mesh_stiffness / me))


def test_conversion_formulas():
    g = GearGeometry(torque_Nm=20.0, te_amplitude_um=2.0, half_backlash_um=5.0,
                     nominal_length_um=10.0, bearing_stiffness_N_per_m=2e9,
                     bearing_damping_p_Ns_per_m=500.0, bearing_damping_g_Ns_per_m=900.0,
                     mesh_damping_ratio=0.06, eps_stiffness=0.2, friction_mu=0.05,
                     speed_rpm=3000.0)
    p = g.to_model_parameters()
    assert isinstance(p, ModelParameters)
    km, me = g.mesh_stiffness, g.equivalent_mass
    assert p.Fm == pytest.approx(20.0 / (0.036 * km * 1e-5))
    assert p.Fe == pytest.approx(0.2) and p.b == pytest.approx(0.5)
    assert p.xi == 0.06 and p.eps == 0.2
    assert p.rho_p == pytest.approx(me / g.mass_p)
    assert p.kappa_py == pytest.approx(2e9 / km * me / g.mass_p)
    assert p.kappa_gz == pytest.approx(2e9 / km * me / g.mass_g)
    assert p.xi_py == pytest.approx(500.0 / (2 * g.mass_p * g.natural_frequency))
    assert p.xi_gz == pytest.approx(900.0 / (2 * g.mass_g * g.natural_frequency))
    assert p.friction == pytest.approx(0.05 * g.friction_arm / 0.036)
    assert p.var_ratio_order == pytest.approx(2 / 18)
    # w = 2 pi (zp n / 60) / w_n: 18 teeth at 3000 rpm mesh at 900 Hz
    assert p.w == pytest.approx(2 * math.pi * 900.0 / g.natural_frequency, rel=1e-12)


def test_round_trip_from_dimensionless():
    target = ModelParameters(Fm=0.3, Fe=0.5, eps=0.25, xi=0.06, b=0.8, friction=0.02,
                             phi_e=-0.5, rho_p=0.4, rho_g=0.1, kappa_py=40.0, xi_py=0.03,
                             xi_gy=0.05)
    g = GearGeometry.from_dimensionless(target)
    p = g.to_model_parameters()
    for name in ("Fm", "Fe", "eps", "xi", "b", "friction", "phi_e", "kappa_py", "xi_py", "xi_gy"):
        assert getattr(p, name) == pytest.approx(getattr(target, name), rel=1e-9), name


@pytest.mark.parametrize(
    "kw, name",
    [({"module_mm": -4.0}, "module_mm"), ({"zp": 17}, "zg"), ({"zp": 2.5}, "zp"),
     ({"face_width_mm": 0.0}, "face_width_mm"), ({"pressure_angle_deg": 50.0},
                                                 "pressure_angle_deg"),
     ({"friction_mu": 1.5}, "friction_mu"), ({"torque_Nm": float("nan")}, "torque_Nm"),
     ({"speed_rpm": 0.0}, "speed_rpm"), ({"mass_p_kg": -1.0}, "mass_p_kg"),
     ({"eps_stiffness": "x"}, "eps_stiffness")],
)
def test_bad_values_raise_one_clear_error(kw, name):
    with pytest.raises(ParameterError, match=name):
        GearGeometry(**kw)


def test_unknown_key_and_bad_tooth_number():
    with pytest.raises(ParameterError, match="unknown gear parameter 'bogus'"):
        GearGeometry.from_mapping({"bogus": 1})
    with pytest.raises(ParameterError, match="zn1"):
        iso_flexibility(3, 36)


def test_masses_from_density_and_given_masses():
    g = GearGeometry()
    # solid steel disk on R_p = 36 mm, 20 mm wide: M = 7850 pi 0.036^2 0.02 kg, I = M R^2 / 2
    m = 7850.0 * math.pi * 0.036**2 * 0.02
    assert g.mass_p == pytest.approx(m, rel=1e-12)
    assert g.inertia_p == pytest.approx(0.5 * m * 0.036**2, rel=1e-12)
    assert g.mass_g == pytest.approx(4 * m, rel=1e-12)  # R_g = 2 R_p
    # disks: Me = Ip Ig / (Ip Rg^2 + Ig Rp^2) = 0.4 M_p, so rho_p = 0.4 and rho_g = 0.1
    assert g.equivalent_mass == pytest.approx(0.4 * m, rel=1e-12)
    # aluminium halves the masses' density; given masses replace the disks, inertia follows
    assert GearGeometry(density_kg_per_m3=2700.0).mass_p == pytest.approx(m * 2700 / 7850)
    h = GearGeometry(mass_p_kg=1.0)
    assert h.mass_p == 1.0 and h.inertia_p == pytest.approx(0.5 * 0.036**2)
    assert h.to_dict()["mass_p_kg"] == 1.0 and h.to_dict()["mass_g_kg"] is None
