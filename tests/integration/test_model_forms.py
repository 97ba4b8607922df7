"""Model-form options of the one field against independent references.

Each option is checked against scipy's DOP853 on the equations written out here, *not* calling
``gearsim.dynamics.model``: the reference integrates the stiffness-path form of Eq 2-3 in the mesh
coordinate ``q`` (rotations and bearing projections, without the transmission error), where the
error enters only through the mesh force ``K(t) f(q - e, b) + C (q' - beta e')`` and there is no
inertial forcing; the model integrates the deflection ``x = q - e`` (docs/model.md, "Model
forms"). The friction arm is the sawtooth of Eq 9 evaluated with ``mod`` of the absolute time,
the contact-only damping with the actual contact state. Switches are located by
DOP853's event detection and the integration restarts there, so the reference keeps its order
across every kink.

Paths checked: scalar DP5, scalar RK4 and the batched SIMD kernel (``run_periods_batched``),
bit-identical to scalar RK4. The Jacobian-vector product (``field_tangent``) is checked by
finite differences in each option, and the coupled mesh-mode frequency against the eigenvalues
of the Lagrangian mass and stiffness matrices in physical coordinates.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from reference import reference_settings
from scipy.integrate import solve_ivp
from scipy.linalg import eigh

from gearsim.cell.simulate import run_periods
from gearsim.dynamics import model as m
from gearsim.dynamics.parameters import (
    ModelParameters,
    ParameterError,
    at_axis_w,
    mesh_mode_ratio,
)
from gearsim.numerics.batch import run_periods_batched
from gearsim.study.config import Study

ROOT = Path(__file__).resolve().parents[2]
N_PER = 10  # mesh periods compared
DP5 = reference_settings(method="dp5", rtol=1e-11, atol=1e-13)
RK4 = reference_settings(method="rk4", steps_per_period=1024)

# a 6-DOF impacting cell (1-1-0 at the standard set) with moderately stiff bearings
BASE = ModelParameters(w=0.9, Fm=0.1185, Fe=0.2115, eps=0.3175, xi=0.0609, b=1.0,
                       phi_e=-0.7258, friction=0.0, rho_p=0.4, rho_g=0.1, kappa_py=40.0,
                       kappa_pz=40.0, kappa_gy=10.0, kappa_gz=10.0)

FORMS = {
    # transmission error through the stiffness path, damper without the error rate
    "te_damping_0": dict(te_damping=0.0),
    "te_damping_half": dict(te_damping=0.5),
    # mesh damping only in contact
    "damping_contact": dict(mesh_damping_contact=1.0),
    "damping_contact_half_te0": dict(mesh_damping_contact=0.5, te_damping=0.0),
    # time-varying friction arm of Eq 9 (sawtooth), friction large enough to matter
    "friction_arm": dict(friction=0.08, friction_arm_var=0.8),
    "friction_arm_te_half": dict(friction=0.05, friction_arm_var=1.24, te_damping=0.5),
    # bearings as Eq 1 / Eq 13: independent soft supports with radial clearance
    "bearings_clearance": dict(kappa_py=6.0, kappa_pz=9.0, kappa_gy=3.0, kappa_gz=4.0,
                               xi_py=0.04, xi_pz=0.05, xi_gy=0.03, xi_gz=0.035,
                               b_py=0.02, b_pz=0.01, b_gy=0.03, b_gz=0.015, w=0.7),
}


# ---------------------------------------------------------------- the independent reference
def _dz(s, g):
    return s - g if s > g else (s + g if s < -g else 0.0)


class Reference:
    """Eq 1-4, 9 (as reconstructed) in the coordinates (q, u_py, u_pz, u_gy, u_gz), written out.

    ``q = R_p theta_p - R_g theta_g + (y_p - y_g) cos(alpha) + (z_p - z_g) sin(alpha)`` over b_c;
    the transmission error ``e(tau) = Fe cos(w tau + phi_e)`` enters the mesh force only.
    """

    def __init__(self, p: ModelParameters):
        self.p = p
        d = p.to_dict()
        self.gaps = [d[f"b_{n}"] for n in ("py", "pz", "gy", "gz")]
        self.kap = [d[f"kappa_{n}"] for n in ("py", "pz", "gy", "gz")]
        self.zb = [d[f"xi_{n}"] for n in ("py", "pz", "gy", "gz")]
        self.dirs = [math.cos(p.alpha), math.sin(p.alpha)] * 2
        dof6 = p.model == "6dof"  # the single-DOF model: rigid bearings (no coupling)
        self.rho = [p.rho_p, p.rho_p, p.rho_g, p.rho_g] if dof6 else [0.0] * 4
        self.sgn = [-1.0, -1.0, 1.0, 1.0]  # pinion pushed back, gear pushed forward

    def e(self, t):
        p = self.p
        return p.Fe * math.cos(p.w * t + p.phi_e)

    def de(self, t):
        p = self.p
        return -p.Fe * p.w * math.sin(p.w * t + p.phi_e)

    def force(self, t, y, contact):
        p = self.p
        q, dq = y[0], y[1]
        k = 1.0 + p.eps * math.cos(p.w * t)
        c = 2.0 * p.xi * (1.0 if contact else 1.0 - p.mesh_damping_contact)
        return k * _dz(q - self.e(t), p.b) + c * (dq - p.te_damping * self.de(t))

    def friction(self, t, half):
        """gamma lambda L_p(t) / mean(L_p): L_p a sawtooth over the mesh period (Eq 9)."""
        p = self.p
        T = 2.0 * math.pi / p.w
        theta = 2.0 * math.pi * ((t % T) / T)
        if theta < 1e-9 and half % 2 == 1:  # the end of the second half, not the start
            theta = 2.0 * math.pi
        lam = 1.0 if half % 2 == 0 else -1.0
        return p.friction * lam * (1.0 + p.friction_arm_var * (theta / math.pi - 1.0))

    def rhs(self, t, y, contact, half):
        F = self.force(t, y, contact)
        acc = np.zeros(10)
        for j in range(4):
            u, du = y[2 + 2 * j], y[3 + 2 * j]
            acc[3 + 2 * j] = (-2.0 * self.zb[j] * du - self.kap[j] * _dz(u, self.gaps[j])
                              + self.sgn[j] * self.rho[j] * F * self.dirs[j])
        a = acc[3::2]
        ddq = (self.p.Fm - F * (1.0 + self.friction(t, half))
               + (a[0] - a[2]) * self.dirs[0] + (a[1] - a[3]) * self.dirs[1])
        out = np.empty(10)
        out[0::2] = y[1::2]
        out[1] = ddq
        out[3::2] = a
        return out

    def switches(self):
        """Event functions: mesh x = q - e = +/- b, bearing u = +/- gap (when a gap is set)."""
        p = self.p
        evs = [lambda t, y, *a: y[0] - self.e(t) - p.b, lambda t, y, *a: y[0] - self.e(t) + p.b]
        for j in range(4):
            if self.gaps[j] > 0:
                k, g = 2 + 2 * j, self.gaps[j]
                evs.append(lambda t, y, *a, k=k, g=g: y[k] - g)
                evs.append(lambda t, y, *a, k=k, g=g: y[k] + g)
        for ev in evs:
            ev.terminal = True
        return evs

    def sections(self, x0, n):
        """Section states (in the model's coordinates x = q - e) at tau = 0, T, ..., nT."""
        p = self.p
        T = 2.0 * math.pi / p.w
        y = np.array(x0, dtype=float)
        y[0] += self.e(0.0)
        y[1] += self.de(0.0)
        out = [self._to_x(0.0, y)]
        evs = self.switches()
        for half in range(2 * n):
            t, t1 = half * T / 2, (half + 1) * T / 2
            while t < t1 - 1e-12:
                x = y[0] - self.e(t)
                # the contact state of the coming stretch (at a switch: where the motion goes)
                xd = y[1] - self.de(t)
                contact = abs(x) > p.b + 1e-11 or (abs(abs(x) - p.b) <= 1e-11 and x * xd > 0)
                r = solve_ivp(lambda tt, yy, c=contact, h=half: self.rhs(tt, yy, c, h), (t, t1), y,
                              method="DOP853", rtol=1e-12, atol=1e-14, events=evs)
                y = r.y[:, -1]
                t_new = r.t[-1]
                if r.status == 1 and t_new <= t + 1e-13:  # an event at the start: step past it
                    r = solve_ivp(lambda tt, yy, c=contact, h=half: self.rhs(tt, yy, c, h),
                                  (t, min(t1, t + 1e-7)), y, method="DOP853", rtol=1e-12,
                                  atol=1e-14)
                    y, t_new = r.y[:, -1], r.t[-1]
                t = t_new
            if half % 2 == 1:
                out.append(self._to_x(t1, y))
        return np.array(out)

    def _to_x(self, t, y):
        x = np.array(y)
        x[0] -= self.e(t)
        x[1] -= self.de(t)
        return x


def _start(p):
    return m.static_state(p.to_array())


@pytest.fixture(scope="module")
def batched():
    """All forms in one batched run (RK4 lanes), from the static state, N_PER periods."""
    cells = [BASE.with_(**kw) for kw in FORMS.values()]
    y0 = np.array([np.concatenate([_start(p), np.eye(10)[0]]) for p in cells])
    out, finals, status, _ = run_periods_batched(cells, y0, N_PER, RK4)
    assert np.all(status == 0)
    return dict(zip(FORMS, out, strict=True))


@pytest.mark.parametrize("name", list(FORMS))
def test_form_against_dop853_reference(name, batched):
    p = BASE.with_(**FORMS[name])
    y0 = _start(p)
    ref = Reference(p).sections(y0, N_PER)
    # the option changes the motion (the test can fail): against the same cell in today's form
    today = p.with_(te_damping=1.0, mesh_damping_contact=0.0, friction_arm_var=0.0, b_py=0.0,
                    b_pz=0.0, b_gy=0.0, b_gz=0.0)
    assert np.abs(ref - Reference(today).sections(y0, N_PER)).max() > 1e-3
    dp5 = run_periods(p, y0, N_PER, DP5).summaries.section
    np.testing.assert_allclose(dp5, ref[:N_PER], atol=1e-7, err_msg=f"{name}: DP5")
    rk4 = run_periods(p, y0, N_PER, RK4, tangent=True).summaries.section
    np.testing.assert_allclose(rk4, ref[:N_PER], atol=1e-6, err_msg=f"{name}: RK4")
    # batched lanes against scalar RK4: bit-identical in today's form (tests/unit/test_batch.py); in
    # the te_damping forms the two compiled paths fuse the new products differently (~1e-15)
    np.testing.assert_allclose(batched[name].section, rk4, rtol=0, atol=1e-12,
                               err_msg=f"{name}: batched")


def test_bearing_clearance_cell_switches_in_its_bearings():
    p = BASE.with_(**FORMS["bearings_clearance"])
    r = run_periods(p, _start(p), 4, DP5, event_capacity=10_000)
    assert np.any(r.events_code >= 4), "the clearance cell must switch in its bearings"


def test_default_form_equals_the_stiffness_path_with_full_damper():
    """te_damping = 1 (today): x'' = Fm + Fe w^2 cos(...) - F is the stiffness-path form in x."""
    y0 = _start(BASE)
    ref = Reference(BASE).sections(y0, N_PER)
    dp5 = run_periods(BASE, y0, N_PER, DP5).summaries.section
    np.testing.assert_allclose(dp5, ref[:N_PER], atol=1e-7)


# ---------------------------------------------------------------- the Jacobian
@pytest.mark.parametrize("name", list(FORMS))
@pytest.mark.parametrize("region", [1, 0, -1])
def test_tangent_is_the_jacobian(name, region):
    p = BASE.with_(**FORMS[name]).to_array()
    rng = np.random.default_rng(7)
    mode = np.array([region, 1, -1, 0, 1, 1], dtype=np.int64)
    mode[m.MODE_FRICTION] = -1
    for t in (0.3, 2.9, 5.1):
        y = rng.normal(size=2 * m.N_STATE)
        dy = np.zeros(2 * m.N_STATE)
        m.rhs(t, y, p, mode, dy, True)
        jz = dy[m.N_STATE:].copy()
        h = 1e-6
        fp, fm_ = np.zeros(20), np.zeros(20)
        m.rhs(t, np.concatenate([y[:10] + h * y[10:], y[10:]]), p, mode, fp, False)
        m.rhs(t, np.concatenate([y[:10] - h * y[10:], y[10:]]), p, mode, fm_, False)
        fd = (fp[:10] - fm_[:10]) / (2 * h)
        np.testing.assert_allclose(jz, fd, rtol=1e-7, atol=1e-7, err_msg=f"{name} t={t}")


def test_default_options_pack_exact_zeros():
    p = Study.load().parameters().model.to_array()
    assert p[m.P_VTE] == 0.0 and p[m.P_XIO] == 0.0 and p[m.P_GAM1] == 0.0


# ---------------------------------------------------------------- frequency scale
def _lagrangian_mesh_mode(p: ModelParameters) -> float:
    """Coupled mesh-mode frequency over sqrt(Km / Me) from M, K in physical coordinates.

    Coordinates (theta_p, theta_g, y_p, z_p, y_g, z_g); Km = Me = 1, R_p = 1, R_g = 2,
    I_p / R_p^2 = I_g / R_g^2 = 2 (so Me = 1), M_i = Me / rho_i, K_ij = kappa_ij Km / rho_i.
    """
    Rp, Rg = 1.0, 2.0
    Ip, Ig = 2.0 * Rp**2, 2.0 * Rg**2
    Mp, Mg = 1.0 / p.rho_p, 1.0 / p.rho_g
    Mm = np.diag([Ip, Ig, Mp, Mp, Mg, Mg])
    ca, sa = math.cos(p.alpha), math.sin(p.alpha)
    g = np.array([Rp, -Rg, ca, sa, -ca, -sa])  # d(mesh deflection) / d(coordinates)
    kb = np.array([0, 0, p.kappa_py / p.rho_p, p.kappa_pz / p.rho_p, p.kappa_gy / p.rho_g,
                   p.kappa_gz / p.rho_g])
    K = np.outer(g, g) + np.diag(kb)
    lam, vec = eigh(K, Mm)
    keep = lam > 1e-9  # drop the rigid rotation
    lam, vec = lam[keep], vec[:, keep]
    mesh = (g @ vec) ** 2
    total = np.einsum("ik,ij,jk->k", vec, K, vec)
    return math.sqrt(lam[np.argmax(mesh / total)])


@pytest.mark.parametrize("kappa", [(40.0, 40.0, 10.0, 10.0), (3.0, 5.0, 2.0, 8.0),
                                   (400, 400, 100, 100)])
def test_mesh_mode_ratio_against_the_lagrangian(kappa):
    p = BASE.with_(**dict(zip(("kappa_py", "kappa_pz", "kappa_gy", "kappa_gz"), kappa,
                              strict=True)))
    r = mesh_mode_ratio(p)
    assert r == pytest.approx(_lagrangian_mesh_mode(p), rel=1e-10)
    assert r < 1.0
    assert mesh_mode_ratio(p.with_(model="1dof")) == 1.0
    assert at_axis_w(p, 1.3, "coupled").w == pytest.approx(1.3 * r, rel=1e-14)
    assert at_axis_w(p, 1.3).w == 1.3


def test_stiff_bearings_approach_the_mesh_frequency():
    p = BASE.with_(kappa_py=4e4, kappa_pz=4e4, kappa_gy=1e4, kappa_gz=1e4)
    assert 1.0 - mesh_mode_ratio(p) < 1e-3


# ---------------------------------------------------------------- bad values
@pytest.mark.parametrize("key, value", [("te_damping", 1.5), ("mesh_damping_contact", -0.1),
                                        ("friction_arm_var", 11.0)])
def test_bad_option_value_is_one_clear_error(key, value):
    with pytest.raises(ParameterError, match=rf"'{key}'.*allowed range"):
        ModelParameters(**{key: value})


def _cli(args, cwd):
    env = dict(os.environ)
    env.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    return subprocess.run([sys.executable, "-m", "gearsim", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=120)


def test_bad_option_value_in_the_config_and_flags_exits_2(tmp_path):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text("parameters: {mesh_damping_contact: 2.0}\n")
    for args, words in ((["point", "-w", "1", "--configfile", str(cfg)],
                         ["parameters.mesh_damping_contact", "[0, 1]"]),
                        (["point", "-w", "1", "--set", "te_damping=-1"], ["te_damping", "[0, 1]"])):
        r = _cli(args, tmp_path)
        err = r.stderr.strip()
        assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
        for w in words:
            assert w in err, (w, err)


def test_unknown_frequency_scale():
    with pytest.raises(ParameterError, match="frequency_scale"):
        at_axis_w(BASE, 1.0, "paper")


# ---------------------------------------------------------------- the sweep method
def test_sweep_from_a_fixed_start_is_independent_cells():
    """``sweeps.<name>.start: rest``: every cell from the static state (no continuation)."""
    from gearsim.cell.simulate import simulate_cell
    from gearsim.study.sweeps import sweep_frame

    st = reference_settings(method="rk4", transient=30, transient_continuation=10, chunk=8,
                             max_periods=16, tangent_lead=0)
    base = BASE.with_(model="1dof")
    ws = np.array([0.55, 0.95])
    rest = sweep_frame(base, "w", ws, "forward", st, start="rest")
    cont = sweep_frame(base, "w", ws, "forward", st)
    for k, w in enumerate(ws):
        ref = simulate_cell(base.with_(w=float(w)), settings=st)
        np.testing.assert_array_equal(np.array(rest["poincare_x"][k]), ref.poincare[:, 0])
    # the continued second cell started elsewhere (its transient is the shorter one)
    assert not np.array_equal(np.array(cont["poincare_x"][1]), np.array(rest["poincare_x"][1]))


# ---------------------------------------------------------------- the mesh force of every form
@pytest.mark.parametrize("name", list(FORMS))
def test_mesh_force_helpers_follow_the_reference(name):
    p = BASE.with_(**FORMS[name])
    arr = p.to_array()
    ref = Reference(p)
    P = m.field_params(arr, 0, 1)
    rng = np.random.default_rng(5)
    tau = rng.uniform(0, 20, 50)
    x = rng.uniform(-2.5, 2.5, 50)
    v = rng.normal(size=50)
    want = []
    for t, xx, vv in zip(tau, x, v, strict=True):
        q = np.zeros(10)
        q[0], q[1] = xx + ref.e(t), vv + ref.de(t)  # the reference works in q = x + e
        want.append(ref.force(t, q, abs(xx) > p.b))
    got_series = m.mesh_force_series(arr, tau, x, v)
    r0 = np.where(x > p.b, 1.0, np.where(x < -p.b, -1.0, 0.0))
    got = [m.mesh_force_full(math.cos(p.w * t), math.sin(p.w * t), xx, vv, P, rr, abs(rr))
           for t, xx, vv, rr in zip(tau, x, v, r0, strict=True)]
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(got_series, want, rtol=1e-12, atol=1e-13)
    if name == "bearings_clearance":  # force unchanged by the bearings
        old = [m.mesh_force(math.cos(p.w * t), xx, vv, P, rr, abs(rr))
               for t, xx, vv, rr in zip(tau, x, v, r0, strict=True)]
        assert old == got


def test_sweep_start_is_validated(tmp_path):
    from gearsim.errors import ConfigError
    from gearsim.study import config as gcfg

    f = tmp_path / "s.yaml"
    f.write_text("sweeps:\n  s1: {name: w, min: 0.5, max: 0.9, n: 3, start: rest}\n")
    assert gcfg.study_config([f], root=ROOT)["sweeps"]["s1"]["start"] == "rest"
    f.write_text("sweeps:\n  s1: {name: w, min: 0.5, max: 0.9, n: 3, start: fixed}\n")
    with pytest.raises(ConfigError, match=r"sweeps.s1.start.*continuation.*rest"):
        gcfg.study_config([f], root=ROOT)



# ---------------------------------------------------------------- saltation (contact-only damping)
@pytest.mark.parametrize("model", ["1dof", "6dof"])
def test_monodromy_with_contact_damping_matches_dop853_finite_differences(model):
    """Damping only in contact makes the field jump at x = +/-b: the monodromy needs the
    saltation matrix at each mesh switch. Reference: central finite differences of the
    DOP853 section map of the equations written out above (no gearsim integrator)."""
    from gearsim.numerics.variational import monodromy

    p = BASE.with_(mesh_damping_contact=1.0, model=model)
    r = run_periods(p, _start(p), 30, DP5, event_capacity=1000)
    y0 = r.state[:10].copy()
    n = 2
    chk = run_periods(p, y0, n, DP5, start_period=30, event_capacity=1000)
    mesh = chk.events_code[chk.events_code < 4]
    assert mesh.size >= 2, "the orbit must switch mesh contact inside the window"
    d = m.n_evolved(p.to_array())
    _, M, status = monodromy(p, y0, n, DP5, start_period=30)
    assert status == 0
    ref = Reference(p)
    h = 1e-6
    fd = np.zeros((d, d))
    for i in range(d):
        e = np.zeros(10)
        e[i] = h
        fd[:, i] = (ref.sections(y0 + e, n)[-1, :d] - ref.sections(y0 - e, n)[-1, :d]) / (2 * h)
    scale = np.abs(fd).max()
    np.testing.assert_allclose(M, fd, rtol=0, atol=2e-5 * scale)


@pytest.mark.parametrize("method", ["rk4", "dp5"])
def test_kmax_tracker_records_the_mesh_force_of_the_form(method):
    """The per-period force extremes (Kmax) follow the form's force: against the maximum of the
    reference force over a finely sampled trajectory of the same cell."""
    from gearsim.cell.simulate import trajectory

    p = BASE.with_(te_damping=0.0, mesh_damping_contact=0.5, model="1dof")
    st = RK4 if method == "rk4" else DP5
    y0 = _start(p)
    n, k = 4, 1024
    s = run_periods(p, y0, n, st).summaries
    tr = trajectory(p, y0, periods=n, samples_per_period=k, transient=0, settings=RK4)
    ref = Reference(p)
    F = []
    for t, y in zip(tr.tau, tr.state, strict=True):
        q = np.array(y, dtype=float)
        q[0], q[1] = y[0] + ref.e(t), y[1] + ref.de(t)
        F.append(ref.force(t, q, abs(y[0]) > p.b))
    F = np.array(F)
    fmax = np.array([F[i * k:(i + 1) * k + 1].max() for i in range(n)])
    fmin = np.array([F[i * k:(i + 1) * k + 1].min() for i in range(n)])
    scale = np.abs(F).max()
    np.testing.assert_allclose(s.fmax, fmax, rtol=0, atol=2e-3 * scale)
    if method == "rk4":
        # RK4 samples every grid point; DP5's tracker reads its step ends, switch points and the
        # x extrema only, so it can miss the damper force's extremum inside the backlash (fmin)
        np.testing.assert_allclose(s.fmin, fmin, rtol=0, atol=2e-3 * scale)
    # today's force (K f + 2 xi x') would differ by more: the test can fail
    x = tr.state[:, 0]
    f = np.where(x > p.b, x - p.b, np.where(x < -p.b, x + p.b, 0.0))
    old = (1 + p.eps * np.cos(p.w * tr.tau)) * f + 2 * p.xi * tr.state[:, 1]
    assert np.abs(old.max() - F.max()) > 2e-2 * scale or np.abs(old.min() - F.min()) > 2e-2 * scale
    if method == "rk4":
        out, _, status, _ = run_periods_batched([p], np.concatenate([y0, np.eye(10)[0]])[None, :],
                                                n, RK4)
        np.testing.assert_allclose(out[0].fmax, s.fmax, rtol=0, atol=1e-12)
