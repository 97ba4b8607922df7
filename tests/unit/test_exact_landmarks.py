"""The model form named beside the exact-landmark table."""

from gearsim.analysis.exact_landmarks import form_name, model_form

TODAY = {
    "sweep": {"name": "w", "min": 0.1, "max": 2.5, "n": 1201, "direction": "forward",
              "fixed": {}},
    "parameters": {"Fm": 0.12, "rho_p": 0.4, "rho_g": 0.1, "kappa_py": 40.0, "kappa_pz": 40.0,
                   "kappa_gy": 10.0, "kappa_gz": 10.0, "b_py": 0.0, "b_pz": 0.0, "b_gy": 0.0,
                   "b_gz": 0.0, "te_damping": 1.0, "mesh_damping_contact": 0.0,
                   "model": "6dof"},
    "integration": {"method": "rk4", "steps_per_period": 256},
}


def test_base_form_is_named_with_its_settings():
    assert form_name(TODAY) == "single_dof"
    text = model_form(TODAY)
    for part in ("6DOF", "rho_p 0.4", "kappa 40/40/10/10", "no clearance", "inertial load",
                 "mesh damping always", "friction arm: its mean", "w over sqrt(Km / Me)",
                 "sweep start: continuation", "RK4, 256 steps per period"):
        assert part in text, part


def test_every_option_shows_in_the_name_and_the_text():
    other = {**TODAY, "sweep": {**TODAY["sweep"], "start": "rest",
                                "fixed": {"mesh_damping_contact": 1.0}},
             "parameters": {**TODAY["parameters"], "te_damping": 0.0, "b_py": 0.5,
                            "friction_arm_var": 0.5}}
    name = form_name(other)
    for part in ("te_damping=0", "contact_damping=1", "friction_arm", "bearing_clearance",
                 "fixed_start"):
        assert part in name, part
    text = model_form(other)
    assert "te_damping 0" in text and "contact-only" in text and "clearance 0.5/0/0/0" in text
    assert "friction_arm_var 0.5" in text and "sweep start: rest" in text
    one = {**TODAY, "parameters": {**TODAY["parameters"], "model": "1dof"}}
    assert form_name(one) == "1dof" and "rigid bearings" in model_form(one)


def test_unknown_provenance_is_said_not_guessed():
    assert form_name(None) == "?"
    assert "unknown" in model_form({})
