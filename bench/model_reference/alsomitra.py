"""Independent Python (numpy/scipy) implementation of the Alsomitra plate model of
the shared docs/MODEL.md (its facts restated in the repository as docs/model.md), used to produce golden values for samara's Rust
tests and as the peer of the simulation benchmark. Written from the document, not from
samara's Rust code.
"""
import math

import numpy as np

C_L1, C_L2, C_D0, C_D1, C_DPI2 = 5.18218452125279, 0.807506506794260, 0.105977518471870, 4.93681162104530, 1.49958010664229
C_CP0, C_CP1, C_CP2, C_R = 0.238565281050545, 2.85289007725274, 0.368933365279324, 1.73001889433847
L, M, RHO_F, A, B, S = 0.07, 3.175e-4, 1.225, 0.03375, 5.0e-4, 0.1745
RHO_S = M / (math.pi * A * B)
M_P = 4 * M / (math.pi * RHO_F * L * L * S)
GAMMA = RHO_F / (RHO_S - RHO_F)
I0 = M * (A**2 + B**2) / (RHO_F * L**4) + 1 / 32
ALPHA0 = 14 * math.pi / 180
DELTA = 6 * math.pi / 180
HALF_PI = math.pi / 2


def F_att(alpha):
    return (1 - math.tanh((-alpha - ALPHA0) / DELTA)) / 2


def coeffs_plate(alpha, variant):
    F = F_att(alpha)
    CL = -(F * C_L1 * math.sin(-alpha) + (1 - F) * C_L2 * math.sin(-2 * alpha))
    if variant == "plate6":
        CD = F * (C_D0 + 0.683 * C_D1 * math.sin(alpha) * math.sin(alpha)) + 0.66 * math.cos(2.143 * alpha + math.pi) + 0.66
    else:
        CD = F * (C_D0 + C_D1 * math.sin(alpha**2)) + (1 - F) * C_DPI2 * math.sin(alpha) ** 2
    eps = F * (C_CP0 - C_CP1 * alpha**2) + (1 - F) * C_CP2 * (1 + alpha / HALF_PI)
    return CL, CD, eps


def coeffs_full(alpha):
    def q(g):
        Fq = (1 - math.tanh((g - ALPHA0) / DELTA)) / 2
        cl = Fq * C_L1 * math.sin(g) + (1 - Fq) * C_L2 * math.sin(2 * g)
        cd = Fq * (C_D0 + C_D1 * math.sin(g**2)) + (1 - Fq) * C_DPI2 * math.sin(g) ** 2
        cp = Fq * (C_CP0 - C_CP1 * g**2) + (1 - Fq) * C_CP2 * (1 - g / HALF_PI)
        return cl, cd, cp

    q1, q2, q3, q4 = q(math.pi - abs(alpha)), q(abs(alpha)), q(alpha), q(math.pi - alpha)
    a = alpha
    ind = lambda c: 1.0 if c else 0.0  # noqa: E731
    CL = q1[0] * ind(-math.pi <= a <= -HALF_PI) - q2[0] * ind(-HALF_PI < a <= 0) + q3[0] * ind(0 < a <= HALF_PI) - q4[0] * ind(HALF_PI < a <= math.pi)
    CD = q1[1] * ind(-math.pi <= a < -HALF_PI) + q2[1] * ind(-HALF_PI <= a < 0) + q3[1] * ind(0 <= a < HALF_PI) + q4[1] * ind(HALF_PI <= a <= math.pi)
    eps = -q1[2] * ind(-math.pi <= a <= -HALF_PI) + q2[2] * ind(-HALF_PI <= a <= 0) + q3[2] * ind(0 <= a <= HALF_PI) - q4[2] * ind(HALF_PI <= a <= math.pi)
    return CL, CD, eps


def rhs(variant, s, e):
    """Derivative of the state (7 entries for plate6/full, 6 for reduced)."""
    vx, vy, w, th = s[0], s[1], s[2], s[3]
    alpha = math.atan(vy / vx)
    ur = vy - w * e
    V = math.sqrt(vx**2 + ur**2)
    if variant == "full":
        CL, CD, eps = coeffs_full(alpha)
        Om = abs(w)
        p, qq = (2 * e + 1) ** 4, (2 * e - 1) ** 4
        P = (p + qq) + (p - qq) if 2 * e <= 1 else (p + qq) - (p - qq)
    else:
        CL, CD, eps = coeffs_plate(alpha, variant)
        Om = math.sqrt(w**2 + 1e-5)
        P = ((2 * e + 1) ** 4 + (2 * e - 1) ** 4) + ((2 * e + 1) ** 4 - (2 * e - 1) ** 4)
    LTx, LTy = (2 / math.pi) * CL * V * ur, (2 / math.pi) * CL * V * (-vx)
    LRx, LRy = (-2 / math.pi) * C_R * w * ur, (-2 / math.pi) * C_R * w * (-vx)
    Dx, Dy = (-2 / math.pi) * CD * V * vx, (-2 / math.pi) * CD * V * ur
    tau = (-C_DPI2 / (32 * math.pi)) * w * Om * P
    I = I0 + e**2
    dw = (tau + (LTy + Dy) * (eps - e) - GAMMA * e * math.cos(th)) / I
    dvx = ((M_P + 1) * w * vy - e * w**2 + (LTx + LRx) + Dx - math.sin(th)) / M_P
    dvy = (-M_P * w * vx + e * dw + (LTy + LRy) + Dy - math.cos(th)) / (M_P + 1)
    dx = vx * math.cos(th) - vy * math.sin(th)
    dy = vx * math.sin(th) + vy * math.cos(th)
    out = [dvx, dvy, dw, w, dx, dy]
    if variant != "reduced":
        x, y, E = s[4], s[5], s[6]
        out.append(0.07 * (y + dy) + 0.07 * (x + dx) - E)
    return np.array(out)


def pid_step(err, e_prev):
    ex = 0.19 + err * 0.05 + (e_prev - err) * (-0.5)
    return min(max(ex, 0.181), 0.193)


def fly(variant, y0, controller, integrate, steps=40, period=0.5):
    """Sample-and-hold flight; `integrate(f, y, period) -> y_end`. Returns the list of
    (state_end, ex) per control step. controller: 'pid' or a float (constant ex)."""
    s = np.array([1.0, 0, 0, 0, 0, y0] + ([0.0] if variant != "reduced" else []))
    e_prev = 0.0
    rows = []
    for _ in range(steps):
        if controller == "pid":
            err = s[6]
            ex = pid_step(err, e_prev)
            e_prev = err
        else:
            ex = float(controller)
        if variant != "reduced":
            s = s.copy()
            s[6] = 0.0
        s = integrate(lambda t, y: rhs(variant, y, ex), s, period)
        rows.append((s.copy(), ex))
    return rows


def solve_ivp_integrator(method="DOP853", rtol=1e-10, atol=1e-12):
    from scipy.integrate import solve_ivp

    def integ(f, y, period):
        sol = solve_ivp(f, (0.0, period), y, method=method, rtol=rtol, atol=atol)
        return sol.y[:, -1]

    return integ
