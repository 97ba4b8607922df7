"""Fig 1: drawn schematic of the 6-DOF bending-torsional model of the curve-face gear pair.

Drawn, not simulated: the non-circular driving gear ``p`` (pitch curve of order ``n1 = 2``) and
the curve-face driven gear ``g`` (face of order ``n2 = 4``), each on bearings modelled as a
linear spring + damper in ``Y`` and ``Z`` (with radial clearance ``B_i``), the mesh as the
time-varying spring ``K(t)`` + damper ``C_n`` with the backlash ``2B`` and the transmission error
``e(t)`` along the line of action (pressure angle ``alpha``), and the coordinates
``{y_p, z_p, theta_p, y_g, z_g, theta_g}``.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Arc, Circle, FancyArrowPatch, Polygon

_INK = "#222222"


def _unit(p0, p1):
    d = np.asarray(p1, float) - np.asarray(p0, float)
    L = float(np.hypot(*d))
    return d / L, np.array([-d[1], d[0]]) / L, L


def spring(ax, p0, p1, *, coils: int = 6, width: float = 0.16, lead: float = 0.18,
           colour=_INK, lw=1.2):
    """Zig-zag spring from ``p0`` to ``p1``."""
    u, n, L = _unit(p0, p1)
    p0 = np.asarray(p0, float)
    s = [0.0, lead * L]
    k = 2 * coils
    s += list(np.linspace(lead * L, (1 - lead) * L, k + 1)[1:-1])
    s += [(1 - lead) * L, L]
    off = [0.0, 0.0] + [width * (1 if i % 2 == 0 else -1) for i in range(k - 1)] + [0.0, 0.0]
    pts = np.array([p0 + si * u + oi * n for si, oi in zip(s, off, strict=True)])
    ax.plot(pts[:, 0], pts[:, 1], color=colour, lw=lw, solid_joinstyle="miter")


def dashpot(ax, p0, p1, *, width: float = 0.16, colour=_INK, lw=1.2):
    """Damper (dashpot) from ``p0`` to ``p1``."""
    u, n, L = _unit(p0, p1)
    p0 = np.asarray(p0, float)
    a = p0 + 0.35 * L * u
    b = p0 + 0.62 * L * u
    ax.plot(*zip(p0, a + 0.0 * n, strict=True), color=colour, lw=lw)
    # cylinder (open towards p0)
    cyl = [a + width * n, b + width * n, b - width * n, a - width * n]
    ax.plot(*zip(*cyl, strict=True), color=colour, lw=lw)
    # piston
    c = p0 + 0.5 * L * u
    ax.plot(*zip(c + 0.8 * width * n, c - 0.8 * width * n, strict=True), color=colour, lw=lw)
    ax.plot(*zip(c, np.asarray(p1, float) - 0.0 * u, strict=True), color=colour, lw=lw)


def spring_damper(ax, p0, p1, *, gap: float = 0.28, **kw):
    """Spring and damper in parallel between ``p0`` and ``p1`` (with end bars)."""
    u, n, L = _unit(p0, p1)
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    a0, a1 = p0 + 0.12 * L * u, p1 - 0.12 * L * u
    ax.plot(*zip(p0, a0, strict=True), color=_INK, lw=1.2)
    ax.plot(*zip(p1, a1, strict=True), color=_INK, lw=1.2)
    ax.plot(*zip(a0 + gap * n, a0 - gap * n, strict=True), color=_INK, lw=1.2)
    ax.plot(*zip(a1 + gap * n, a1 - gap * n, strict=True), color=_INK, lw=1.2)
    spring(ax, a0 + gap * n, a1 + gap * n, **kw)
    dashpot(ax, a0 - gap * n, a1 - gap * n)


def ground(ax, p, direction, *, size: float = 0.45):
    """Hatched ground symbol at ``p``; ``direction`` points from the ground into the body."""
    u = np.asarray(direction, float) / np.hypot(*direction)
    n = np.array([-u[1], u[0]])
    p = np.asarray(p, float)
    ax.plot(*zip(p + size * n, p - size * n, strict=True), color=_INK, lw=1.6)
    for t in np.linspace(-size, size, 7):
        q = p + t * n
        ax.plot(*zip(q, q - 0.16 * u - 0.12 * n, strict=True), color=_INK, lw=0.8)


def arrow(ax, p0, p1, text=None, *, colour="#1f4fd6", offset=(0.05, 0.05), fs=11, lw=1.3):
    ax.add_patch(FancyArrowPatch(p0, p1, arrowstyle="-|>", mutation_scale=11, color=colour,
                                 lw=lw, zorder=6))
    if text:
        ax.text(p1[0] + offset[0], p1[1] + offset[1], text, color=colour, fontsize=fs,
                zorder=7)


def rot_arrow(ax, centre, r, text, *, colour="#1f4fd6", start=30, end=140, fs=11):
    ax.add_patch(Arc(centre, 2 * r, 2 * r, theta1=start, theta2=end, color=colour, lw=1.3,
                     zorder=6))
    t = np.radians(end)
    tip = np.array(centre) + r * np.array([np.cos(t), np.sin(t)])
    tang = np.array([-np.sin(t), np.cos(t)])
    ax.add_patch(FancyArrowPatch(tip - 0.05 * tang, tip + 0.05 * tang, arrowstyle="-|>",
                                 mutation_scale=11, color=colour, lw=1.3, zorder=6))
    m = np.radians(0.5 * (start + end))
    ax.text(centre[0] + 1.2 * r * np.cos(m), centre[1] + 1.2 * r * np.sin(m), text,
            color=colour, fontsize=fs, ha="center", va="center", zorder=7)


def noncircular_gear(ax, centre, *, a: float = 1.35, k: float = 0.18, order: int = 2,
                     teeth: int = 18, depth: float = 0.12):
    """Non-circular gear: pitch curve r = a (1 - k^2) / (1 - k cos(order theta)) with teeth."""
    th = np.linspace(0, 2 * np.pi, 2000)
    r = a * (1 - k**2) / (1 - k * np.cos(order * th))
    # teeth as a smooth square-ish wave on the pitch curve
    wave = np.tanh(3 * np.sin(teeth * th)) * depth
    R = r + wave
    xy = np.c_[centre[0] + R * np.cos(th), centre[1] + R * np.sin(th)]
    ax.add_patch(Polygon(xy, closed=True, fc="#dce9f7", ec=_INK, lw=1.0, zorder=2))
    ax.plot(centre[0] + r * np.cos(th), centre[1] + r * np.sin(th), ls="-.", lw=0.6,
            color="#555555", zorder=3)
    ax.add_patch(Circle(centre, 0.22, fc="white", ec=_INK, lw=1.0, zorder=3))
    ax.plot(*centre, "k+", ms=8, zorder=4)


def curve_face_gear(ax, centre, *, R: float = 2.0, H: float = 0.55, order: int = 4,
                    teeth: int = 36, amp: float = 0.22):
    """Curve-face gear seen from the side: a disc whose toothed face undulates ``order`` times
    per turn (the face height varies with the polar angle)."""
    cx, cy = centre
    x = np.linspace(-R, R, 1200)
    th = np.arccos(np.clip(x / R, -1, 1))
    face = cy + H / 2 + amp * (1 + np.cos(order * th)) / 2
    tooth = 0.07 * np.tanh(3 * np.sin(teeth * th))
    top = face + np.abs(tooth)
    body = np.r_[np.c_[cx + x, top], [[cx + R, cy - H / 2], [cx - R, cy - H / 2]]]
    ax.add_patch(Polygon(body, closed=True, fc="#fde9d9", ec=_INK, lw=1.0, zorder=2))
    ax.plot(cx + x, face, ls="-.", lw=0.6, color="#555555", zorder=3)
    # shaft
    ax.add_patch(Polygon([[cx - 0.18, cy - H / 2], [cx + 0.18, cy - H / 2],
                          [cx + 0.18, cy - H / 2 - 1.0], [cx - 0.18, cy - H / 2 - 1.0]],
                         closed=True, fc="#eeeeee", ec=_INK, lw=1.0, zorder=2))
    ax.plot(cx, cy, "k+", ms=8, zorder=4)


def figure1():
    """Fig 1: the dynamic model of the curve-face gear transmission (schematic)."""
    fig, ax = plt.subplots(figsize=(11.0, 7.4))
    ax.set_aspect("equal")
    ax.axis("off")
    Op = np.array([0.0, 2.3])  # driver (non-circular gear) centre
    Og = np.array([5.6, -0.2])  # curve-face gear centre
    noncircular_gear(ax, Op)
    curve_face_gear(ax, Og)
    ax.text(-3.7, 4.55, "non-circular gear p\n(driver, $z_p$ = 18, $n_1$ = 2)", fontsize=9)
    ax.text(7.2, -2.75, "curve-face gear g\n(driven, $z_g$ = 36, $n_2$ = 4)", fontsize=9)
    ax.text(Op[0] + 0.25, Op[1] - 0.55, r"$M_p, I_p$", fontsize=9, zorder=8)
    ax.text(Og[0] - 1.6, Og[1] - 0.1, r"$M_g, I_g$", fontsize=9, zorder=8)

    # --- bearings of p: Y (horizontal, from the left) and Z (vertical, from above);
    # the connection to the hub runs under the gear body
    ax.plot([Op[0] - 1.5, Op[0]], [Op[1], Op[1]], color=_INK, lw=1.2, zorder=1)
    ground(ax, Op + [-3.6, 0], (1, 0))
    spring_damper(ax, Op + [-3.6, 0], Op + [-1.5, 0])
    ax.text(Op[0] - 2.75, Op[1] + 0.42, r"$K_{py}$", fontsize=9)
    ax.text(Op[0] - 2.75, Op[1] - 0.62, r"$C_{py}$", fontsize=9)
    ax.plot([Op[0], Op[0]], [Op[1] + 1.35, Op[1]], color=_INK, lw=1.2, zorder=1)
    ground(ax, Op + [0, 3.45], (0, -1))
    spring_damper(ax, Op + [0, 3.45], Op + [0, 1.35])
    ax.text(Op[0] + 0.55, Op[1] + 2.35, r"$K_{pz}$", fontsize=9)
    ax.text(Op[0] - 0.95, Op[1] + 2.35, r"$C_{pz}$", fontsize=9)
    # --- bearings of g: Y (horizontal, from the right) and Z (vertical, from below) on the shaft
    gy0 = Og + [0.18, -0.275 - 0.45]
    ground(ax, gy0 + [2.7, 0], (-1, 0))
    spring_damper(ax, gy0 + [2.7, 0], gy0)
    ax.text(gy0[0] + 1.3, gy0[1] - 0.62, r"$K_{gy}$", fontsize=9)
    ax.text(gy0[0] + 1.75, gy0[1] + 0.35, r"$C_{gy}$", fontsize=9)
    gz0 = Og + [0, -0.275 - 1.0]
    ground(ax, gz0 + [0, -2.2], (0, 1))
    spring_damper(ax, gz0 + [0, -2.2], gz0)
    ax.text(gz0[0] - 0.95, gz0[1] - 1.2, r"$K_{gz}$", fontsize=9)
    ax.text(gz0[0] + 0.42, gz0[1] - 1.2, r"$C_{gz}$", fontsize=9)
    ax.text(-3.7, -3.55, "bearings: linear springs + dampers in Y and Z,\n"
            r"radial clearance dead zone $\pm B_i$ (Eq 1)", fontsize=8.5, color="#444444")

    # --- mesh: spring-damper with backlash along the line of action (pressure angle alpha)
    alpha = np.radians(20.0)
    A = Op + 1.25 * np.array([np.cos(-0.95), np.sin(-0.95)])  # contact side of p
    B = Og + np.array([-1.25, 0.55])  # face of g
    u, n, L = _unit(A, B)
    mid = A + 0.55 * L * u
    g0, g1 = mid - 0.16 * u, mid + 0.16 * u  # backlash gap
    spring_damper(ax, A, g0 - 0.05 * u, gap=0.2, coils=4, width=0.11)
    for q in (g0, g1):
        ax.plot(*zip(q + 0.22 * n, q - 0.22 * n, strict=True), color="#d62728", lw=1.8)
    ax.plot(*zip(g1, B, strict=True), color=_INK, lw=1.2)
    ax.plot(*zip(g0 - 0.05 * u, g0, strict=True), color=_INK, lw=1.2)
    ax.annotate(r"backlash $2B$", xy=mid + 0.25 * n, xytext=mid + 1.6 * n + 0.3 * u,
                fontsize=9, color="#d62728",
                arrowprops={"arrowstyle": "->", "color": "#d62728", "lw": 0.8})
    ax.text(*(A + 0.3 * L * u + 0.5 * n), r"$K(t)$", fontsize=10, ha="center")
    ax.text(-3.7, -2.85, r"mesh: $K(t) = K_m + K_a\cos(\omega_h t + \varphi)$, "
            r"$C_n = 2\xi\sqrt{K_m M_e}$,"
            "\n" r"dead zone $f(X_n, B)$ (Eq 3-4), along the line of action (dotted)", fontsize=8.5,
            color="#444444")
    ax.text(*(A + 0.28 * L * u - 0.62 * n), r"$C_n$", fontsize=10, ha="center")
    ax.text(*(A - 0.2 * u - 1.35 * n), "transmission error\n"
            r"$e(t) = E_m \sin(\omega_h t + \varphi)$", fontsize=8.5, ha="center",
            color="#444444")
    # line of action, X_n and the pressure angle at the contact on g
    lo0, lo1 = A - 0.9 * u, B + 0.7 * u
    ax.plot(*zip(lo0, lo1, strict=True), ls=":", color="#888888", lw=1.0, zorder=1)
    arrow(ax, g1 + 0.45 * n + 0.3 * u, g1 + 0.45 * n + 1.1 * u, None, colour="#d62728")
    ax.text(*(g1 + 0.75 * n + 0.7 * u), r"$X_n$", color="#d62728", fontsize=11,
            ha="center", va="center")
    ang_u = np.arctan2(u[1], u[0])
    ax.add_patch(Arc(B, 1.4, 1.4, theta1=np.degrees(ang_u), theta2=np.degrees(ang_u + alpha),
                     color="#666666", lw=0.9))
    tip = B + 1.0 * np.array([np.cos(ang_u + alpha), np.sin(ang_u + alpha)])
    ax.plot(*zip(B, tip, strict=True), color="#888888", lw=0.8, ls=":")
    ax.text(*(B + 0.85 * np.array([np.cos(ang_u + alpha / 2), np.sin(ang_u + alpha / 2)])),
            r"$\alpha$", fontsize=10, color="#444444", va="center")

    # --- coordinates and loads
    arrow(ax, Op, Op + [0.95, 0], r"$y_p$", offset=(0.05, 0.08))
    arrow(ax, Op, Op + [0, 0.95], r"$z_p$", offset=(0.1, -0.15))
    rot_arrow(ax, Op, 0.6, r"$\theta_p$", start=120, end=230)
    arrow(ax, Og + [0, 0.02], Og + [1.1, 0.02], r"$y_g$", offset=(0.05, 0.05))
    arrow(ax, Og, Og + [0, 1.25], r"$z_g$", offset=(0.1, 0.0))
    rot_arrow(ax, Og + [0, -0.9], 0.5, r"$\theta_g$", start=200, end=340)
    rot_arrow(ax, Op + [-1.75, -1.4], 0.3, "", colour="#2ca02c", start=90, end=300)
    ax.text(Op[0] - 2.95, Op[1] - 2.0, r"$T_p$ (input torque)", fontsize=9, color="#2ca02c")
    ax.text(Og[0] + 1.05, Og[1] + 1.0, r"$T_g$ (load torque)", fontsize=9, color="#2ca02c")
    ax.text(-3.7, 6.2, r"6 DOF: generalised coordinates $\{y_p, z_p, \theta_p, y_g, z_g, "
            r"\theta_g\}$; dimensionless mesh displacement $x = X_n / b_c$", fontsize=10)
    ax.set_xlim(-3.9, 9.4)
    ax.set_ylim(-3.9, 6.6)
    fig.tight_layout()
    return fig
