#!/usr/bin/env python3
"""
indep2 / dyn.py -- start-up transients of the indep2 two-shaft industrial gas
turbine generator set, from standstill to steady load, logged at 1 Hz.

Uses sim.py's thermodynamics, component maps, health scaling, drive-train
losses and noise definitions unchanged above the map floor; adds
  * two shaft inertias (gas generator; power turbine + gearbox + generator),
  * a quasi-steady gas path solved at every time step for flow compatibility
    (compressor, combustor, HPT, inter-turbine duct, PT, exhaust) with the
    GG and PT speeds and the fuel flow as inputs,
  * similarity extrapolation of the compressor map below 55 % corrected
    speed, low-blade-speed-ratio (stall torque) extension of the turbine
    efficiency characteristics, low-speed bearing friction,
  * VIGV / bleed actuators, an electric starter, a PT brake,
  * a min/max-select fuel control (GG speed loop, N-dot acceleration and
    deceleration limits, TIT limit, fuel/CDP ratio limits) with cascaded
    PT-speed governor and MW load controller, auto-synchroniser and breaker,
  * first-order thermocouple lags.
Python 3 standard library only.  `python3 dyn.py` writes startups/.
See README.md section "Start-ups (dyn.py)" and dynamics.txt.
"""
import math
import os
import random
import sys
import time
from datetime import datetime, timedelta, timezone

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.dont_write_bytecode = True      # importing sim.py leaves no __pycache__ behind
import sim  # noqa: E402
from sim import (AIR, FUEL, LHV_MOLAR, LHV, T_FUEL, D, S, PREF, ISO_T, ISO_P,  # noqa: E402
                 HEALTH_KEYS, products, mix_streams, cap_fn, eff_fn, cmap_raw,
                 elec_from_shaft, shaft_from_elec, k2f, pa2psi, kgs2lbh)

OUTDIR = os.path.join(HERE, 'startups')

# design point of sim.py (fills sim.S)
T4_DESIGN = sim.design()
sim.X_DESIGN = [1.0, D['BETA_D'], T4_DESIGN, S['PRH'], S['PRP']]
_W_D, _Q_D, _E_D, _QS_D = cmap_raw(1.0, D['BETA_D'], 0.0)

RPM2RAD = 2.0 * math.pi / 60.0
W_GG_DES = D['NGG'] * RPM2RAD          # rad/s at 11 200 rpm
W_PT_DES = D['NPT'] * RPM2RAD          # rad/s at 8 500 rpm (synchronous)

# =============================================================================
# Dynamic-model parameters (all documented in dynamics.txt)
# =============================================================================
P = dict(
    J_GG=15.0,          # kg m^2, compressor + HPT + accessory gearbox share
    J_PT=120.0,         # kg m^2, PT + gearbox + generator referred to PT speed
    # map floor and extrapolation
    N_L=0.55,           # lowest corrected speed treated as 'map' (sim.py form)
    S0=0.12,            # log-speed scale of the blend to similarity exponents
    KW_LOW=1.0,         # flow ~ n^1 at the low-speed limit (similarity)
    KQ_LOW=2.0,         # (PR-1) ~ n^2 at the low-speed limit (similarity)
    EFF_FLOOR=0.5,      # compressor efficiency falls to this fraction of its 55 % value
    R_L=0.6,            # turbine velocity ratio below which the stall-torque cubic applies
    STALL=2.0,          # turbine stall torque / torque at nu_opt (same gas conditions)
    # low-speed bearing friction (fades out between 20 and 40 % speed)
    TF_GG=12.0,         # N m
    TF_PT=45.0,         # N m (PT + gearbox + generator bearings, at PT speed)
    TF_FADE=(0.20, 0.40),
    # actuators
    TAU_VIGV=1.0, TAU_BLEED=1.0,
    # sensors (first-order thermocouple lags)
    TAU_CDT=2.0, TAU_T48=4.0, TAU_EGT=5.0,
)

N_REST = 0.004      # below this GG speed fraction the gas path is scaled (no solve)


# =============================================================================
# Extended compressor map
# =============================================================================
def _dw_dn(n, beta):
    """analytic derivative of sim.cmap_raw flow (VIGV open) w.r.t. n at fixed beta"""
    p = 1.5 + 1.5 * (1.0 - n)
    wch = n ** p
    dwch = wch * (-1.5 * math.log(n) + p / n)
    f = 1.0 - (1.0 - beta) ** 2
    A = 0.92 - 0.25 * (1.0 - n)
    Bf = 1.0 - A
    w = wch * (A + Bf * f)
    dw = dwch * (A + Bf * f) + wch * (0.25 - 0.25 * f)
    return w, dw


CHOKE_SLOPE = 0.02   # beyond the choke end (beta > 1): w = w_ch (1 + CHOKE_SLOPE (beta-1)^2)


def cmap_rawx(n, beta, vigv):
    """sim.cmap_raw, with the speed line continued beyond its choke end (beta > 1)
    at (nearly) constant flow and falling pressure ratio instead of the
    parabola's turning back.  Identical to sim.cmap_raw for beta <= 1."""
    if beta <= 1.0:
        return cmap_raw(n, beta, vigv)
    w, q, e, qs = cmap_raw(n, beta, vigv)
    wch, _, _, _ = cmap_raw(n, 1.0, vigv)
    return wch * (1.0 + CHOKE_SLOPE * (beta - 1.0) ** 2), q, e, qs


def cmap_ext(n, beta, vigv):
    """sim.cmap extended below N_L.  Returns (w_rel, PR, e_rel, PR_surge)."""
    NL = P['N_L']
    if n >= NL:
        w, q, e, qs = cmap_rawx(n, beta, vigv)
    else:
        wL, qL, eL, qsL = cmap_rawx(NL, beta, vigv)
        wL0, dwL = _dw_dn(NL, min(beta, 1.0))
        kw = NL * dwL / wL0                      # local log-slope of flow at the floor
        kq = sim.MAP_PS_EXP                      # log-slope of (PR-1)
        s = math.log(max(n, 1e-9) / NL)
        s0 = P['S0']
        ex = math.exp(s / s0) - 1.0
        gw = P['KW_LOW'] * s + (kw - P['KW_LOW']) * s0 * ex
        gq = P['KQ_LOW'] * s + (kq - P['KQ_LOW']) * s0 * ex
        w = wL * math.exp(gw)
        q = qL * math.exp(gq)
        qs = qsL * math.exp(gq)
        # efficiency: C1 continuation falling towards EFF_FLOOR * e(N_L) (0.55-0.6 of it at n = 0)
        fe = 1.0 - sim.VIGV_KE * vigv * vigv
        e0L = eL / fe
        de = -2.8 * (NL - 0.96)
        c = de / (e0L * (1.0 - P['EFF_FLOOR']))
        e = eL * (P['EFF_FLOOR'] + (1.0 - P['EFF_FLOOR']) * math.exp(c * (n - NL)))
    return (w / _W_D, 1.0 + (D['PR'] - 1.0) * q / _Q_D, e / _E_D,
            1.0 + (D['PR'] - 1.0) * qs / _Q_D)


# =============================================================================
# Turbine efficiency vs velocity ratio, extended to zero speed (stall torque)
# =============================================================================
def _stall_cubic(K):
    rL, a = P['R_L'], P['STALL']
    fL = 1.0 - K * (rL - 1.0) ** 2
    dfL = -2.0 * K * (rL - 1.0)
    # g = a r + b r^2 + c r^3 ; g(rL) = fL ; g'(rL) = dfL
    A11, A12, B1 = rL * rL, rL ** 3, fL - a * rL
    A21, A22, B2 = 2 * rL, 3 * rL * rL, dfL - a
    det = A11 * A22 - A12 * A21
    b = (B1 * A22 - A12 * B2) / det
    c = (A11 * B2 - A21 * B1) / det
    return a, b, c


CUB_H = _stall_cubic(sim.HPT_K)
CUB_P = _stall_cubic(sim.PT_K)


def g_over_r(r, K, cub):
    """efficiency shape g(r)/r (torque shape); g = sim.eff_fn above R_L"""
    if r >= P['R_L']:
        return (1.0 - K * (r - 1.0) ** 2) / r
    a, b, c = cub
    return a + r * (b + r * c)


# =============================================================================
# Quasi-steady gas path
# =============================================================================
class Inputs:
    __slots__ = ('Ngg', 'Npt', 'Wf', 'vigv', 'bleed', 'Tamb', 'Pamb', 'hp')

    def __init__(self, Ngg, Npt, Wf, vigv, bleed, Tamb, Pamb, hp):
        self.Ngg, self.Npt, self.Wf, self.vigv, self.bleed = Ngg, Npt, Wf, vigv, bleed
        self.Tamb, self.Pamb, self.hp = Tamb, Pamb, hp


def gaspath(u, I, full=False):
    """u = [beta, ln(PR_hpt-1), ln(PR_pt-1)].  Speeds (rpm), fuel (kg/s), VIGV and
    bleed positions are inputs.  Returns residuals [HPT capacity, PT capacity,
    exhaust pressure] (all relative), and the state if full."""
    beta, lh, lp = u
    hp = I.hp
    dgc, dec, dgt, det, dgp, dep = [hp[k] for k in HEALTH_KEYS]
    T1 = I.Tamb
    th = T1 / ISO_T
    n = I.Ngg / D['NGG'] / math.sqrt(th)
    wrel, PR, erel, PRsurge = cmap_ext(n, beta, I.vigv)
    Wc = S['WC'] * wrel * (1.0 - dgc / 100.0)
    eta_c = D['ETA_C'] * erel * (1.0 - dec / 100.0)
    P1 = I.Pamb * (1.0 - S['DPIN'] * (Wc / S['WC']) ** 2)
    W1 = Wc * (P1 / ISO_P) / math.sqrt(th)
    P3 = P1 * PR
    h1 = AIR.h(T1)
    T3s = AIR.T_from_phi(AIR.phi(T1) + math.log(PR), T1 * PR ** 0.2857)
    h3 = h1 + (AIR.h(T3s) - h1) / eta_c
    T3 = AIR.T_from_h(h3, T3s)
    Pc = W1 * (h3 - h1)
    Wbl = I.bleed * W1
    Wngv, Wrot = D['F_NGV'] * W1, D['F_ROT'] * W1
    W31 = W1 - Wbl - Wngv - Wrot
    dpb = D['DP_B'] * (W31 * math.sqrt(T3) / P3 / S['Q31']) ** 2
    P4 = P3 * (1.0 - dpb)
    # combustor: T4 from the fuel flow (enthalpy balance, complete combustion)
    Wf = I.Wf
    n_air = W31 / AIR.M
    n_f = Wf / FUEL.M
    if n_f > 0.0:
        m4, _ = products(n_air, n_f)
        H_in = n_air * AIR.Hm(T3) + n_f * (FUEL.Hm(T_FUEL) - (1 - D['ETA_B']) * LHV_MOLAR)
        W4 = W31 + Wf
        T4 = m4.T_from_h(H_in / W4, T3 + Wf / W31 * LHV / 1250.0)
    else:
        m4, W4, T4 = AIR, W31, T3
    W41, m41, T41 = mix_streams([(W4, m4, T4), (Wngv, AIR, T3)])
    P41 = P4
    PRh = 1.0 + math.exp(lh)
    Q41 = W41 * math.sqrt(T41) / P41
    Q41m = S['Q41'] * cap_fn(PRh, sim.HPT_M) / cap_fn(S['PRH'], sim.HPT_M) * (1.0 - dgt / 100.0)
    r1 = Q41 / Q41m - 1.0
    h41 = m41.h(T41)
    T42s = m41.T_from_phi(m41.phi(T41) - math.log(PRh), T41 / PRh ** 0.25)
    dhs = h41 - m41.h(T42s)
    w_gg = I.Ngg * RPM2RAD
    rh = sim.HPT_RD * (w_gg / W_GG_DES) * math.sqrt(S['DHSH'] / dhs)
    etamax_h = D['ETA_H'] / eff_fn(sim.HPT_RD, sim.HPT_K) * (1.0 - det / 100.0)
    gr_h = g_over_r(rh, sim.HPT_K, CUB_H)
    eta_h = etamax_h * gr_h * rh
    # torque = W dhs eta / omega, written so that it stays finite at omega = 0
    tau_h = W41 * math.sqrt(dhs * S['DHSH']) * etamax_h * sim.HPT_RD * gr_h / W_GG_DES
    h42 = h41 - eta_h * dhs
    T42 = m41.T_from_h(h42, T42s)
    Ph = W41 * eta_h * dhs
    P45 = P41 / PRh
    W45, m45, T45 = mix_streams([(W41, m41, T42), (Wrot, AIR, T3)])
    Q45 = W45 * math.sqrt(T45) / P45
    P48 = P45 * (1.0 - D['DP_ITD'] * (Q45 / S['Q45']) ** 2)
    T48 = T45
    Q48 = W45 * math.sqrt(T48) / P48
    PRp = 1.0 + math.exp(lp)
    Q48m = S['Q48'] * cap_fn(PRp, sim.PT_M) / cap_fn(S['PRP'], sim.PT_M) * (1.0 - dgp / 100.0)
    r3 = Q48 / Q48m - 1.0
    P5 = P48 / PRp
    h48 = m45.h(T48)
    T5s = m45.T_from_phi(m45.phi(T48) - math.log(PRp), T48 / PRp ** 0.25)
    dhsp = h48 - m45.h(T5s)
    w_pt = I.Npt * RPM2RAD
    rp = sim.PT_RD * (w_pt / W_PT_DES) * math.sqrt(S['DHSP'] / dhsp)
    etamax_p = D['ETA_P'] / eff_fn(sim.PT_RD, sim.PT_K) * (1.0 - dep / 100.0)
    gr_p = g_over_r(rp, sim.PT_K, CUB_P)
    eta_p = etamax_p * gr_p * rp
    tau_p = W45 * math.sqrt(dhsp * S['DHSP']) * etamax_p * sim.PT_RD * gr_p / W_PT_DES
    h5 = h48 - eta_p * dhsp
    T5 = m45.T_from_h(h5, T5s)
    Ppt = W45 * eta_p * dhsp
    dPex = S['KEX'] * W45 ** 2 * T5 / I.Pamb
    # exhaust: P5 = Pamb + loss, scaled by the compressor pressure rise (well conditioned at any speed)
    r4 = (P5 - I.Pamb - dPex) / (max(P3 - I.Pamb, 0.0) + dPex + 1.0)
    res = [r1, r3, r4]
    if not full:
        return res
    tau_c = Pc / w_gg if w_gg > 0 else 0.0
    return res, dict(
        Tamb=I.Tamb, Pamb=I.Pamb, T1=T1, P1=P1, Nc=n, N_gg=I.Ngg, N_pt=I.Npt, beta=beta,
        vigv=I.vigv, bleed=I.bleed, Wc=Wc, W1=W1, PR=PR, PR_surge=PRsurge,
        SM=PRsurge / PR - 1.0, eta_c=eta_c, T3=T3, P3=P3, P_comp=Pc, tau_c=tau_c,
        W_bleed=Wbl, W31=W31, dp_comb=dpb, P4=P4, T4=T4, W_fuel=Wf, FAR=Wf / W31,
        T41=T41, W41=W41, PR_hpt=PRh, eta_hpt=eta_h, r_hpt=rh, P_hpt=Ph, tau_h=tau_h,
        T45=T45, P45=P45, P48=P48, T48=T48, W45=W45, PR_pt=PRp, eta_pt=eta_p, r_pt=rp,
        P_pt=Ppt, tau_pt=tau_p, P5=P5, T5=T5, res=res)


# =============================================================================
# Gas-path solver (Newton with Jacobian reuse, continuation fallback)
# =============================================================================
GP_TOL = 1e-10


def _lin3(J, b):
    return sim.lin_solve(J, b)


def _jac(u, I, r):
    J = [[0.0] * 3 for _ in range(3)]
    for j in range(3):
        h = 1e-7 * max(abs(u[j]), 1.0)
        up = list(u)
        up[j] += h
        rp = gaspath(up, I)
        for i in range(3):
            J[i][j] = (rp[i] - r[i]) / h
    return J


class GPSolver:
    def __init__(self):
        self.J = None
        self.nfail = 0
        self.nsolve = 0
        self.nevals = 0
        self.maxres = 0.0

    def _newton(self, u0, I, maxit=30):
        u = list(u0)
        try:
            r = gaspath(u, I)
        except (ValueError, ZeroDivisionError, OverflowError, RuntimeError):
            return None, 0
        self.nevals += 1
        nr = max(abs(v) for v in r)
        fresh = False
        it = 0
        while nr >= GP_TOL and it < maxit:
            it += 1
            if self.J is None:
                self.J = _jac(u, I, r)
                self.nevals += 3
                fresh = True
            try:
                du = _lin3(self.J, [-v for v in r])
            except ZeroDivisionError:
                if fresh:
                    return None, it
                self.J = None
                continue
            lam, ok = 1.0, False
            for _ in range(20):
                un = [u[0] + lam * du[0], u[1] + lam * du[1], u[2] + lam * du[2]]
                un[0] = min(max(un[0], -0.6), 1.6)
                un[1] = min(max(un[1], -30.0), 4.0)
                un[2] = min(max(un[2], -30.0), 4.0)
                try:
                    rn = gaspath(un, I)
                    self.nevals += 1
                    nrn = max(abs(v) for v in rn)
                    if nrn < nr:
                        ok = True
                        break
                except (ValueError, ZeroDivisionError, OverflowError, RuntimeError):
                    pass
                lam *= 0.5
            if not ok or nrn > 0.3 * nr:
                if fresh and not ok:
                    return None, it
                if not fresh:
                    self.J = None      # refresh the Jacobian and retry from here
                    if ok:
                        u, r, nr = un, rn, nrn
                    continue
            u, r, nr = un, rn, nrn
            fresh = False
        if nr < GP_TOL:
            self.maxres = max(self.maxres, nr)
            return u, it
        return None, it

    def solve(self, u0, I, I_prev=None, u_prev=None):
        self.nsolve += 1
        u, it = self._newton(u0, I)
        if u is not None:
            return u
        # continuation in the inputs from the last converged point
        if I_prev is not None and u_prev is not None:
            for nst in (4, 16, 64):
                uu = list(u_prev)
                good = True
                for k in range(1, nst + 1):
                    lam = k / nst
                    Ik = Inputs(I_prev.Ngg + lam * (I.Ngg - I_prev.Ngg),
                                I_prev.Npt + lam * (I.Npt - I_prev.Npt),
                                I_prev.Wf + lam * (I.Wf - I_prev.Wf),
                                I_prev.vigv + lam * (I.vigv - I_prev.vigv),
                                I_prev.bleed + lam * (I.bleed - I_prev.bleed),
                                I.Tamb, I.Pamb, I.hp)
                    self.J = None
                    un, it = self._newton(uu, Ik)
                    if un is None:
                        good = False
                        break
                    uu = un
                if good:
                    return uu
        self.nfail += 1
        raise RuntimeError('gas path did not converge')


# =============================================================================
# Starter, sequence and control constants (dynamics.txt)
# =============================================================================
NGG_DES = D['NGG']
NPT_SYNC = D['NPT']
SEQ = dict(
    T_REST0=10.0,        # s at rest before the start command
    CRANK_RATE=1.0,      # %/s starter (VFD) speed-reference ramp to purge speed
    N_PURGE=0.20,        # purge speed, fraction of 11 200 rpm
    T_PURGE=60.0,        # s purge at purge speed
    N_LIGHT=0.16,        # light-off speed
    LIGHT_RATE=0.5,      # %/s speed-reference ramp down from purge to light-off speed
    T_IGN=3.0,           # s at light-off speed with ignitors on before the fuel valve opens
    WF_LIGHT=0.022,      # kg/s light-off fuel step
    T_LIGHT_HOLD=5.0,    # s light-off fuel held before the acceleration control takes over
    N_CUTOUT=0.55,       # starter cut-out speed
    T_CUTOUT_RAMP=2.0,   # s starter torque ramp-down at cut-out
    N_IDLE=0.58,         # GG idle, fraction of 11 200 rpm (physical); below FSNL on every day
    IDLE_BAND=0.003,     # 'idle reached' when within 0.3 % of idle
    T_WARM=60.0,         # s warm-up at idle (PT brake on)
    PT_RATE=1.5,         # %/s PT speed-reference ramp
    PT_TAU=10.0,         # s final exponential approach of the PT speed reference
    SYNC_BIAS=0.0005,    # auto-synchroniser speed bias (+0.05 % slip)
    SLIP_BAND=0.002,     # breaker closes when |slip| <= 0.2 % ...
    T_SLIP=3.0,          # ... for 3 s
    TAU_PULLIN=0.5,      # s pull-into-step of the PT/generator speed after the breaker closes
    LOAD_RATE=0.1,       # MW/s electrical load ramp
    T_HOLD=720.0,        # s held at the target after the load reference reaches it
    # shutdown
    UNLOAD_TO=0.2,       # MW: breaker opens when unloaded to this
    T_COOL=240.0,        # s cool-down at idle
)
STARTER = dict(TMAX=600.0, N_BASE=0.20)   # N m constant torque up to 20 %, then constant power
CTL = dict(
    DT=0.1,              # s control / integration step
    K_N=0.8,             # 1/s GG speed error -> N-dot demand
    A_EST=55.0,          # %/s per kg/s: nominal d(Ndot)/d(Wf) used to scale the N-dot fuel integrator
    K_A=0.3,             # fraction of the N-dot error corrected per step
    NDOT_MAX=((0.55, 1.2), (0.70, 2.0)),  # (n, %/s): 1.2 %/s up to 55 %, 2 %/s above 70 %
    NDOT_MIN=-2.0,       # %/s deceleration limit
    K_T=0.3,             # fraction of the TIT error corrected per step
    T4_MAX=S['T4'],      # K, the TIT limit of sim.py
    RU_MAX=((0.18, 0.040), (0.40, 0.054), (0.70, 0.054), (0.85, 0.070)),  # (nc, kg/s per bar)
    RU_MIN=0.012,        # kg/s per bar lean blow-out limit
    NGG_MAX=1.05,        # GG speed reference ceiling
    # PT speed governor (outer loop, NGG reference), gains at 8 500 rpm
    KP_PT=3.0, KI_PT=0.25,
    # MW controller (outer loop, NGG reference)
    KP_MW=0.25, KI_MW=0.30,   # as fractions of 1/(dMW/dNGG estimate)
    # starter VFD speed loop
    KP_ST=50.0, KI_ST=20.0,
)


def smoothstep(x, x0, x1):
    if x <= x0:
        return 0.0
    if x >= x1:
        return 1.0
    s = (x - x0) / (x1 - x0)
    return s * s * (3.0 - 2.0 * s)


def sched(x, pts):
    """smooth (C1) piecewise schedule through (x, y) points, flat outside"""
    y = pts[0][1]
    for (x0, y0), (x1, y1) in zip(pts, pts[1:]):
        y += (y1 - y0) * smoothstep(x, x0, x1)
    return y


def starter_curve(n):
    nb = STARTER['N_BASE']
    if n <= nb:
        return STARTER['TMAX']
    return STARTER['TMAX'] * nb / n


def fade(x, x0, x1):
    """1 below x0, 0 above x1, smooth"""
    return 1.0 - smoothstep(x, x0, x1)


def gg_loss_torque(w):
    """sim.py's GG shaft loss (power ~ N^2, i.e. torque ~ N) plus low-speed bearing friction"""
    visc = D['GG_LOSS'] * S['PC'] / W_GG_DES * (w / W_GG_DES)
    coul = P['TF_GG'] * fade(w / W_GG_DES, *P['TF_FADE']) if w > 0 else 0.0
    return visc + coul


P_NL_SYNC = shaft_from_elec(0.0)   # W, PT shaft power to spin the gearbox + generator at sync, no load


def pt_loss_torque(w):
    """gearbox + generator no-load loss (sim.py's at 8 500 rpm, power ~ N^2 below) + friction"""
    visc = P_NL_SYNC / W_PT_DES * (w / W_PT_DES)
    coul = P['TF_PT'] * fade(w / W_PT_DES, *P['TF_FADE']) if w > 0 else 0.0
    return visc + coul


MEAS = ['AMB_T_F', 'AMB_P_PSIA', 'T1_F', 'P1_PSIA', 'NGG_RPM', 'NPT_RPM', 'FUEL_LBH',
        'CDP_PSIA', 'CDT_F', 'T48_F', 'EGT_F', 'MW']


# =============================================================================
# The transient simulation
# =============================================================================
FLOW_KEYS = ('Wc', 'W1', 'W_bleed', 'W31', 'W41', 'W45')
PRES_KEYS = ('P1', 'P3', 'P4', 'P45', 'P48', 'P5')
TEMP_KEYS = ('T3', 'T4', 'T41', 'T45', 'T48', 'T5')


class Engine:
    """One unit on one day with one health: start, run, optional shutdown."""

    def __init__(self, Tamb, Pamb, hp, target_mw):
        self.Tamb, self.Pamb = Tamb, Pamb
        self.hp = {k: float(hp.get(k, 0.0)) for k in HEALTH_KEYS}
        self.target = target_mw
        self.th = Tamb / ISO_T
        self.dt = CTL['DT']
        self.k = 0                      # step counter, t = k dt
        self.wg = 0.0
        self.wp = 0.0
        self.vigv = sim.VIGV_MAX
        self.bleed = sim.BLEED_MAX
        self.Wf = 0.0
        self.flame = False
        self.T3m = self.T48m = self.T5m = Tamb
        self.solver = GPSolver()
        self.u = None
        self.u_prev = None
        self.I_prev = None
        self.phase = 'rest'
        self.ev = {}
        self.st_mode = 'off'
        self.st_nref = 0.0
        self.st_I = 0.0
        self.t_cut = None
        self.brake = True
        self.breaker = False
        self.idle = SEQ['N_IDLE'] * NGG_DES
        self.ngg_ref = self.idle
        self.npt_ref = 0.0
        self.I_pt = 0.0
        self.mw_ref = 0.0
        self.I_mw = 0.0
        self.ngg_base = self.idle
        self.slip_timer = 0.0
        self.t_mark = 0.0
        self.loop = 'off'
        self.mw = 0.0
        self.tau_st = 0.0
        self.done = False
        self.rec = []
        self.nptdot = 0.0
        self.fan_k = 0.0
        self.ref_u, self.ref = self._cold_reference()

    # ------------------------------------------------------------------ gas path
    def _inputs(self, N, Npt, Wf, vigv, bleed):
        return Inputs(N, Npt, Wf, vigv, bleed, self.Tamb, self.Pamb, self.hp)

    def _cold_reference(self):
        """cold (no fuel) gas path at the solve floor N_REST, PT at rest"""
        N = N_REST * NGG_DES
        nc = N / NGG_DES / math.sqrt(self.th)
        I = self._inputs(N, 0.0, 0.0, sim.VIGV_MAX, sim.BLEED_MAX)
        for b0 in (1.23, 1.15, 1.30, 1.0):
            try:
                self.solver.J = None
                u = self.solver.solve([b0, math.log(1.08 * nc * nc), math.log(0.16 * nc * nc)], I)
                break
            except RuntimeError:
                self.solver.nfail -= 1
                u = None
        if u is None:
            raise RuntimeError('no cold reference solution')
        res, g = gaspath(u, I, True)
        self.solver.J = None
        return u, g

    def _scaled(self, N, Npt):
        """below N_REST: similarity scaling of the cold reference solution"""
        gr = self.ref
        s = N / gr['N_gg']
        g = dict(gr)
        for k in FLOW_KEYS:
            g[k] = gr[k] * s
        for k in PRES_KEYS:
            g[k] = self.Pamb + (gr[k] - self.Pamb) * s * s
        for k in TEMP_KEYS:
            g[k] = self.Tamb + (gr[k] - self.Tamb) * s * s
        for k in ('tau_c', 'tau_h'):
            g[k] = gr[k] * s * s
        g['tau_pt'] = gr['tau_pt'] * s * s if Npt == 0.0 else 0.0
        for k in ('P_comp', 'P_hpt'):
            g[k] = gr[k] * s ** 3
        g['P_pt'] = g['tau_pt'] * Npt * RPM2RAD
        g['N_gg'], g['N_pt'] = N, Npt
        g['W_fuel'], g['FAR'] = 0.0, 0.0
        g['vigv'], g['bleed'] = self.vigv, self.bleed
        g['Nc'] = N / NGG_DES / math.sqrt(self.th)
        # a coasting PT keeps stirring (windage-heating) the exhaust gas: T5 - T48 ~ N_PT^2
        g['T5'] = g['T48'] + self.fan_k * Npt * Npt
        g['scaled'] = True
        return g

    def gas(self):
        N = self.wg / RPM2RAD
        Npt = self.wp / RPM2RAD
        if N < N_REST * NGG_DES:
            if self.Wf > 0.0:
                raise RuntimeError('fuel on below the solve floor')
            self.u, self.u_prev, self.I_prev = None, None, None
            return self._scaled(N, Npt)
        I = self._inputs(N, Npt, self.Wf, self.vigv, self.bleed)
        if self.u is None:
            u0, I_prev, u_last = list(self.ref_u), self._inputs(
                N_REST * NGG_DES, Npt, 0.0, self.vigv, self.bleed), list(self.ref_u)
        else:
            u_last, I_prev = self.u, self.I_prev
            if self.u_prev is not None:
                u0 = [2 * a - b for a, b in zip(self.u, self.u_prev)]
            else:
                u0 = list(self.u)
        u = self.solver.solve(u0, I, I_prev, u_last)
        self.u_prev, self.u, self.I_prev = (self.u if self.u is not None else None), u, I
        res, g = gaspath(u, I, True)
        g['scaled'] = False
        self.fan_k = (g['T5'] - g['T48']) / (Npt * Npt) if Npt > 0.0 else 0.0
        return g

    # ------------------------------------------------------------------ one step
    def step(self):
        dt = self.dt
        t = self.k * dt
        g = self.gas()
        N = self.wg / RPM2RAD
        Npt = self.wp / RPM2RAD
        n = N / NGG_DES
        nc = n / math.sqrt(self.th)

        # ---- starter torque (decided in the previous control pass)
        tau_st = self.tau_st
        # ---- GG torque balance
        tau_gas = g['tau_h'] - g['tau_c']
        tloss = gg_loss_torque(self.wg)
        if self.wg <= 0.0 and tau_gas + tau_st <= P['TF_GG']:
            acc_g = 0.0
        else:
            acc_g = (tau_gas + tau_st - tloss) / P['J_GG']
        # ---- PT torque balance
        tloss_p = pt_loss_torque(self.wp)
        if self.brake:
            acc_p = 0.0
        elif self.breaker:
            acc_p = (W_PT_DES - self.wp) / SEQ['TAU_PULLIN']
        elif self.wp <= 0.0 and g['tau_pt'] <= P['TF_PT']:
            acc_p = 0.0
        else:
            acc_p = (g['tau_pt'] - tloss_p) / P['J_PT']
        if self.breaker:
            p_shaft = g['tau_pt'] * self.wp - P['J_PT'] * self.wp * acc_p
            self.mw = elec_from_shaft(p_shaft) / 1e6
        else:
            self.mw = 0.0
        ndot = acc_g / RPM2RAD           # rpm/s
        nptdot = acc_p / RPM2RAD
        self.nptdot = nptdot

        # ---- record (1 Hz)
        if self.k % int(round(1.0 / dt)) == 0:
            self.record(t, g, ndot, nptdot, tau_st, tloss, tloss_p)

        # ---- sequence and control -> Wf, starter torque for the next step
        self.control(t, g, N, Npt, nc, ndot)

        # ---- integrate (explicit Euler, ZOH inputs)
        self.wg = max(0.0, self.wg + dt * acc_g)
        if self.wg < 1e-3 and acc_g <= 0.0:
            self.wg = 0.0
        if self.brake:
            self.wp = 0.0
        else:
            self.wp = max(0.0, self.wp + dt * acc_p)
            if self.wp < 1e-3 and acc_p <= 0.0:
                self.wp = 0.0
        if self.breaker and abs(self.wp - W_PT_DES) < 1e-9 * W_PT_DES:
            self.wp = W_PT_DES
        a_v = 1.0 - math.exp(-dt / P['TAU_VIGV'])
        a_b = 1.0 - math.exp(-dt / P['TAU_BLEED'])
        self.vigv += (sim.vigv_schedule(nc) - self.vigv) * a_v
        self.bleed += (sim.bleed_schedule(nc) - self.bleed) * a_b
        self.T3m += (g['T3'] - self.T3m) * (1.0 - math.exp(-dt / P['TAU_CDT']))
        self.T48m += (g['T48'] - self.T48m) * (1.0 - math.exp(-dt / P['TAU_T48']))
        self.T5m += (g['T5'] - self.T5m) * (1.0 - math.exp(-dt / P['TAU_EGT']))
        self.k += 1

    # ------------------------------------------------------------------ control
    def control(self, t, g, N, Npt, nc, ndot):
        dt = self.dt
        ph = self.phase
        ev = self.ev
        # ----------------------------------------------------- sequencer
        if ph == 'rest':
            if self.k * dt >= SEQ['T_REST0'] and not self.ev.get('shutdown_done'):
                self.phase = 'crank'
                ev['start_cmd'] = t
                self.st_mode = 'speed'
                self.st_nref = N / NGG_DES
                self.st_I = 0.0
        elif ph == 'crank':
            self.st_nref = min(SEQ['N_PURGE'], self.st_nref + SEQ['CRANK_RATE'] / 100.0 * dt)
            if N >= (SEQ['N_PURGE'] - 0.002) * NGG_DES:
                self.phase = 'purge'
                ev['purge_start'] = t
                self.t_mark = t
        elif ph == 'purge':
            if t - self.t_mark >= SEQ['T_PURGE']:
                self.phase = 'to_light'
        elif ph == 'to_light':
            self.st_nref = max(SEQ['N_LIGHT'], self.st_nref - SEQ['LIGHT_RATE'] / 100.0 * dt)
            if self.st_nref <= SEQ['N_LIGHT'] and N <= (SEQ['N_LIGHT'] + 0.002) * NGG_DES:
                self.phase = 'ignition'
                ev['ignition'] = t
                self.t_mark = t
        elif ph == 'ignition':
            if t - self.t_mark >= SEQ['T_IGN']:
                self.phase = 'lightoff'
                ev['light_off'] = t
                self.flame = True
                self.st_mode = 'curve'
                self.t_mark = t
        elif ph == 'lightoff':
            if t - self.t_mark >= SEQ['T_LIGHT_HOLD']:
                self.phase = 'accel'
                self.ngg_ref = self.idle
        elif ph == 'accel':
            if N >= self.idle * (1.0 - SEQ['IDLE_BAND']):
                self.phase = 'warmup'
                ev['idle'] = t
                self.t_mark = t
        elif ph == 'warmup':
            if t - self.t_mark >= SEQ['T_WARM']:
                self.phase = 'pt_accel'
                ev['brake_release'] = t
                self.brake = False
                self.npt_ref = Npt
                self.I_pt = self.ngg_ref - self.idle
        elif ph == 'pt_accel':
            slip = (Npt - NPT_SYNC) / NPT_SYNC
            if abs(slip) <= SEQ['SLIP_BAND']:
                self.slip_timer += dt
            else:
                self.slip_timer = 0.0
            if 'pt_breakaway' not in ev and Npt > 0.0:
                ev['pt_breakaway'] = t
            if 'pt_peak' not in ev or Npt > ev['pt_peak']:
                ev['pt_peak'] = Npt
            if self.slip_timer >= SEQ['T_SLIP'] - 1e-9:
                self.breaker = True
                ev['breaker_close'] = t
                ev['slip_at_close_pct'] = 100.0 * slip
                self.phase = 'load'
                self.mw_ref = max(0.0, self.mw)
                self.ngg_base = self.ngg_ref
                self.I_mw = 0.0
        elif ph == 'load':
            self.mw_ref = min(self.target, self.mw_ref + SEQ['LOAD_RATE'] * dt)
            if self.mw_ref >= self.target - 1e-12:
                self.phase = 'hold'
                ev['ref_at_target'] = t
                self.t_mark = t
        elif ph == 'hold':
            if t - self.t_mark >= SEQ['T_HOLD']:
                self.done = True
        elif ph == 'unload':
            self.mw_ref = max(SEQ['UNLOAD_TO'], self.mw_ref - SEQ['LOAD_RATE'] * dt)
            if self.mw_ref <= SEQ['UNLOAD_TO'] + 1e-12 and self.mw <= SEQ['UNLOAD_TO'] + 0.02:
                self.breaker = False
                ev['breaker_open'] = t
                self.phase = 'cooldown'
                self.ngg_ref = self.idle
                self.t_mark = t
        elif ph == 'cooldown':
            self.ngg_ref = self.idle
            if t - self.t_mark >= SEQ['T_COOL']:
                self.phase = 'coast'
                ev['fuel_off'] = t
                self.flame = False
        elif ph == 'coast':
            if self.wg == 0.0 and self.wp == 0.0:
                self.phase = 'rest'
                ev['at_rest'] = t
                ev['shutdown_done'] = True
                self.done = True
        ph = self.phase

        # ----------------------------------------------------- starter
        if self.st_mode == 'speed':
            e = (self.st_nref * NGG_DES - N) * RPM2RAD
            tmax = starter_curve(N / NGG_DES)
            tau = CTL['KP_ST'] * e + self.st_I
            if not ((tau >= tmax and e > 0) or (tau <= 0.0 and e < 0)):
                self.st_I += CTL['KI_ST'] * e * dt
            self.tau_st = min(max(tau, 0.0), tmax)
        elif self.st_mode == 'curve':
            self.tau_st = starter_curve(N / NGG_DES)
            if N >= SEQ['N_CUTOUT'] * NGG_DES:
                self.st_mode = 'cutout'
                self.t_cut = t
                ev['starter_cutout'] = t
        elif self.st_mode == 'cutout':
            f = 1.0 - (t - self.t_cut) / SEQ['T_CUTOUT_RAMP']
            if f <= 0.0:
                self.st_mode = 'off'
                self.tau_st = 0.0
            else:
                self.tau_st = starter_curve(N / NGG_DES) * f
        else:
            self.tau_st = 0.0

        # ----------------------------------------------------- outer loops -> NGG reference
        if ph == 'pt_accel':
            target = NPT_SYNC * (1.0 + SEQ['SYNC_BIAS'])
            rate = SEQ['PT_RATE'] / 100.0 * NPT_SYNC
            self.npt_ref += min(rate, (target - self.npt_ref) / SEQ['PT_TAU']) * dt
            at_floor = self.ngg_ref <= self.idle + 1e-9
            if at_floor and (Npt > self.npt_ref or self.nptdot > rate):
                self.npt_ref = Npt       # PT runs ahead of the ramp on idle gas power: reference follows
            gs = max(Npt, 2500.0) / NPT_SYNC
            e = self.npt_ref - Npt
            raw = self.idle + self.I_pt + CTL['KP_PT'] * gs * e
            limited = self.loop in ('tit', 'ru_max', 'accel_limit')
            if not ((raw <= self.idle and e < 0) or (raw >= CTL['NGG_MAX'] * NGG_DES and e > 0)
                    or (limited and e > 0)):
                self.I_pt += CTL['KI_PT'] * gs * e * dt
            self.ngg_ref = min(max(raw, self.idle), CTL['NGG_MAX'] * NGG_DES)
        elif ph in ('load', 'hold', 'unload') and self.breaker:
            mwx = max(self.mw, 0.0)
            km = (1.5 + 3.5 * smoothstep(mwx, 2.0, 6.0)) * 1e-3      # MW per rpm, estimate
            e = self.mw_ref - self.mw
            raw = self.ngg_base + self.I_mw + CTL['KP_MW'] / km * e
            limited = self.loop in ('tit', 'ru_max', 'accel_limit')
            if not ((raw <= self.idle and e < 0) or (raw >= CTL['NGG_MAX'] * NGG_DES and e > 0)
                    or (limited and e > 0)):
                self.I_mw += CTL['KI_MW'] / km * e * dt
            self.ngg_ref = min(max(raw, self.idle), CTL['NGG_MAX'] * NGG_DES)

        # ----------------------------------------------------- fuel
        if ph in ('rest', 'crank', 'purge', 'to_light', 'ignition', 'coast') or not self.flame:
            self.Wf = 0.0
            self.loop = 'off'
            return
        if ph == 'lightoff':
            self.Wf = SEQ['WF_LIGHT']
            self.loop = 'lightoff'
            return
        ndmax = sched(n_frac(N), CTL['NDOT_MAX']) * NGG_DES / 100.0
        ndmin = CTL['NDOT_MIN'] * NGG_DES / 100.0
        nd_ref = CTL['K_N'] * (self.ngg_ref - N)
        lab = 'speed'
        if nd_ref >= ndmax:
            nd_ref, lab = ndmax, 'accel_limit'
        elif nd_ref <= ndmin:
            nd_ref, lab = ndmin, 'decel_limit'
        c_n = self.Wf + CTL['K_A'] * (nd_ref - ndot) / (CTL['A_EST'] * NGG_DES / 100.0)
        sT = LHV / (1250.0 * (g['W31'] + self.Wf))
        c_t = self.Wf + CTL['K_T'] * (CTL['T4_MAX'] - g['T4']) / sT
        wf = c_n
        if c_t < wf:
            wf, lab = c_t, 'tit'
        p3bar = g['P3'] / 1e5
        ru_max = sched(nc, CTL['RU_MAX'])
        if wf > ru_max * p3bar:
            wf, lab = ru_max * p3bar, 'ru_max'
        if wf < CTL['RU_MIN'] * p3bar:
            wf, lab = CTL['RU_MIN'] * p3bar, 'ru_min'
        if ph == 'accel' and wf < SEQ['WF_LIGHT']:
            wf, lab = SEQ['WF_LIGHT'], 'start_min'     # start schedule floor = light-off fuel
        self.Wf = max(wf, 0.0)
        self.loop = lab

    # ------------------------------------------------------------------ records
    def record(self, t, g, ndot, nptdot, tau_st, tloss, tloss_p):
        m = {
            'AMB_T_F': k2f(self.Tamb), 'AMB_P_PSIA': pa2psi(self.Pamb), 'T1_F': k2f(self.Tamb),
            'P1_PSIA': pa2psi(g['P1']), 'NGG_RPM': g['N_gg'], 'NPT_RPM': g['N_pt'],
            'FUEL_LBH': kgs2lbh(self.Wf), 'CDP_PSIA': pa2psi(g['P3']), 'CDT_F': k2f(self.T3m),
            'T48_F': k2f(self.T48m), 'EGT_F': k2f(self.T5m), 'MW': self.mw,
        }
        self.rec.append((t, self.phase, m, g, dict(
            ndot=ndot, nptdot=nptdot, tau_st=tau_st, tloss=tloss, tloss_p=tloss_p,
            loop=self.loop, brake=self.brake, breaker=self.breaker,
            ngg_ref=self.ngg_ref if self.loop not in ('off', 'lightoff') else float('nan'),
            npt_ref=self.npt_ref if self.phase == 'pt_accel' else float('nan'),
            mw_ref=self.mw_ref if self.breaker else 0.0, T3m=self.T3m, T48m=self.T48m,
            T5m=self.T5m)))

    # ------------------------------------------------------------------ drivers
    def run_start(self):
        while not self.done:
            self.step()
            if self.k * self.dt > 4000:
                raise RuntimeError('start did not complete')
        self.done = False
        return self

    def run_shutdown(self):
        self.phase = 'unload'
        self.ev['unload_start'] = self.k * self.dt
        while not self.done:
            self.step()
            if self.k * self.dt > 12000:
                raise RuntimeError('shutdown did not complete')
        return self


def n_frac(N):
    return N / NGG_DES


# =============================================================================
# The starts
# =============================================================================
def H(**kw):
    return {k: float(kw.get(k, 0.0)) for k in HEALTH_KEYS}


BASE_MW = D['MW']                      # 'base load' target: 13.0 MW, TIT-limited where needed
STARTS = [
    # name, (T_amb degC, P_amb kPa), target MW, health, description
    ('start_01', (5.0, 101.60), BASE_MW, H(), 'healthy, base load'),
    ('start_02', (27.0, 100.20), BASE_MW, H(), 'healthy, base load (TIT-limited day)'),
    ('start_03', (-3.0, 102.30), 0.70 * BASE_MW, H(), 'healthy, 70 % load'),
    ('start_04', (35.0, 99.10), 0.70 * BASE_MW, H(), 'healthy, 70 % load'),
    ('start_05', (12.0, 101.00), BASE_MW, H(D_GC=1.5, D_EC=0.75), 'compressor fouling 1'),
    ('start_06', (20.0, 100.70), 0.70 * BASE_MW, H(D_GC=3.0, D_EC=1.5), 'compressor fouling 2'),
    ('start_07', (9.0, 101.40), BASE_MW, H(D_GC=4.5, D_EC=2.25), 'compressor fouling 3'),
    ('start_08', (24.0, 100.30), 0.70 * BASE_MW, H(D_GT=-1.0, D_ET=1.2), 'HPT erosion 1'),
    ('start_09', (0.0, 102.00), BASE_MW, H(D_GT=-2.0, D_ET=2.4), 'HPT erosion 2'),
    ('start_10', (17.0, 100.90), 0.70 * BASE_MW, H(D_GP=-1.2, D_EP=1.2), 'PT wear'),
    ('start_11', (30.0, 99.60), 0.72 * BASE_MW,
     H(D_GC=2.5, D_EC=1.0, D_GT=-1.2, D_ET=1.5, D_GP=-0.8, D_EP=0.9), 'combined'),
    ('start_12', (-5.0, 102.50), BASE_MW, H(), 'healthy, base load, coldest day'),
]

START_T0 = datetime(2025, 7, 1, 6, 0, 0, tzinfo=timezone.utc)   # start_01 file begins here
START_DAY_STEP = 5                                               # days between the start files
NOISE_SEED0 = 20250700          # start_XX noise stream: random.Random(NOISE_SEED0 + XX)
LOG_SEED = 20251006             # operations_log noise stream
LOG_T0 = datetime(2025, 10, 6, 0, 0, 0, tzinfo=timezone.utc)
# (start re-run in the log, start time of day); one start per calendar day, in this order
LOG_PLAN = [('start_01', (15, 0)), ('start_03', (7, 30)), ('start_05', (8, 0)),
            ('start_06', (7, 0)), ('start_08', (6, 30))]
LOG_PRE_REST = 3600.0           # s of rest logged before the first start
REST_DT = 10                    # s historian interval while the unit is at rest
STEADY_WINDOW = 300             # s averaged into steady_points.csv

SIG = sim.SIG


def iso(ts):
    return ts.strftime('%Y-%m-%dT%H:%M:%SZ')


def fmt_meas(ts, m, noisy):
    return ','.join([ts] + [(SIG[c][3] if noisy else SIG[c][2]) % m[c] for c in MEAS])


def add_noise(m, rng):
    out = {}
    for c in MEAS:
        kind, sig = SIG[c][0], SIG[c][1]
        gs = rng.gauss(0.0, 1.0)
        out[c] = m[c] + sig * gs if kind == 'abs' else m[c] * (1.0 + sig * gs)
    return out


def rest_meas(Tamb, Pamb):
    return {'AMB_T_F': k2f(Tamb), 'AMB_P_PSIA': pa2psi(Pamb), 'T1_F': k2f(Tamb),
            'P1_PSIA': pa2psi(Pamb), 'NGG_RPM': 0.0, 'NPT_RPM': 0.0, 'FUEL_LBH': 0.0,
            'CDP_PSIA': pa2psi(Pamb), 'CDT_F': k2f(Tamb), 'T48_F': k2f(Tamb),
            'EGT_F': k2f(Tamb), 'MW': 0.0}


INT_COLS = [
    ('timestamp', None), ('t_s', '%d'), ('phase', None), ('fuel_loop', None), ('pt_brake', None),
    ('breaker', None), ('gaspath', None), ('N_gg_rpm', '%.3f'), ('N_pt_rpm', '%.3f'),
    ('Nc_rel', '%.6f'), ('dNgg_dt_rpm_s', '%.3f'), ('dNpt_dt_rpm_s', '%.3f'),
    ('NGG_ref_rpm', '%.2f'), ('NPT_ref_rpm', '%.2f'), ('MW_ref', '%.5f'),
    ('beta', '%.5f'), ('surge_margin_pct', '%.3f'), ('vigv_deg', '%.4f'), ('bleed_frac', '%.6f'),
    ('W1_kgs', '%.5f'), ('W1c_kgs', '%.5f'), ('PR_c', '%.6f'), ('eta_c', '%.5f'),
    ('T3_K', '%.3f'), ('P3_kPa', '%.4f'), ('W_fuel_kgs', '%.6f'), ('FAR', '%.6f'),
    ('T4_TIT_K', '%.3f'), ('T41_SOT_K', '%.3f'), ('W41_kgs', '%.5f'), ('PR_hpt', '%.6f'),
    ('eta_hpt', '%.5f'), ('nu_ratio_hpt', '%.5f'), ('T48_K', '%.3f'), ('P48_kPa', '%.4f'),
    ('W45_kgs', '%.5f'), ('PR_pt', '%.6f'), ('eta_pt', '%.5f'), ('nu_ratio_pt', '%.5f'),
    ('T5_K', '%.3f'), ('P5_kPa', '%.4f'), ('P_comp_MW', '%.5f'), ('P_hpt_MW', '%.5f'),
    ('P_pt_MW', '%.5f'), ('tau_comp_Nm', '%.2f'), ('tau_hpt_Nm', '%.2f'),
    ('tau_starter_Nm', '%.2f'), ('tau_gg_loss_Nm', '%.3f'), ('tau_pt_Nm', '%.2f'),
    ('tau_pt_loss_Nm', '%.3f'), ('P_elec_MW', '%.6f'), ('T3_meas_K', '%.3f'),
    ('T48_meas_K', '%.3f'), ('T5_meas_K', '%.3f'),
]


def internal_row(ts, r):
    t, ph, m, g, x = r
    v = {
        'timestamp': ts, 't_s': t, 'phase': ph, 'fuel_loop': x['loop'],
        'pt_brake': 'on' if x['brake'] else 'off', 'breaker': 'closed' if x['breaker'] else 'open',
        'gaspath': 'scaled' if g.get('scaled') else 'solved',
        'N_gg_rpm': g['N_gg'], 'N_pt_rpm': g['N_pt'], 'Nc_rel': g['Nc'],
        'dNgg_dt_rpm_s': x['ndot'], 'dNpt_dt_rpm_s': x['nptdot'], 'NGG_ref_rpm': x['ngg_ref'],
        'NPT_ref_rpm': x['npt_ref'], 'MW_ref': x['mw_ref'], 'beta': g['beta'],
        'surge_margin_pct': 100 * g['SM'], 'vigv_deg': g['vigv'], 'bleed_frac': g['bleed'],
        'W1_kgs': g['W1'], 'W1c_kgs': g['Wc'], 'PR_c': g['PR'], 'eta_c': g['eta_c'],
        'T3_K': g['T3'], 'P3_kPa': g['P3'] / 1e3, 'W_fuel_kgs': g['W_fuel'], 'FAR': g['FAR'],
        'T4_TIT_K': g['T4'], 'T41_SOT_K': g['T41'], 'W41_kgs': g['W41'], 'PR_hpt': g['PR_hpt'],
        'eta_hpt': g['eta_hpt'], 'nu_ratio_hpt': g['r_hpt'], 'T48_K': g['T48'],
        'P48_kPa': g['P48'] / 1e3, 'W45_kgs': g['W45'], 'PR_pt': g['PR_pt'], 'eta_pt': g['eta_pt'],
        'nu_ratio_pt': g['r_pt'] if g['N_pt'] > 0 else 0.0, 'T5_K': g['T5'],
        'P5_kPa': g['P5'] / 1e3, 'P_comp_MW': g['P_comp'] / 1e6, 'P_hpt_MW': g['P_hpt'] / 1e6,
        'P_pt_MW': g['P_pt'] / 1e6, 'tau_comp_Nm': g['tau_c'], 'tau_hpt_Nm': g['tau_h'],
        'tau_starter_Nm': x['tau_st'], 'tau_gg_loss_Nm': x['tloss'], 'tau_pt_Nm': g['tau_pt'],
        'tau_pt_loss_Nm': x['tloss_p'], 'P_elec_MW': m['MW'], 'T3_meas_K': x['T3m'],
        'T48_meas_K': x['T48m'], 'T5_meas_K': x['T5m'],
    }
    out = []
    for c, f in INT_COLS:
        val = v[c]
        if f is None:
            out.append(str(val))
        elif isinstance(val, float) and math.isnan(val):
            out.append('')
        else:
            out.append(f % val)
    return ','.join(out)


def write_csv(path, header, lines):
    with open(path, 'w', newline='\n') as fh:
        fh.write(','.join(header) + '\n')
        for ln in lines:
            fh.write(ln + '\n')


# =============================================================================
# Run everything
# =============================================================================
def simulate(spec, with_shutdown):
    name, (tc, pk), target, hp, desc = spec
    e = Engine(tc + 273.15, pk * 1e3, hp, target)
    t0 = time.time()
    e.run_start()
    n_start = len(e.rec)
    k_start = e.k
    ev_start = dict(e.ev)
    start_rec = list(e.rec)
    shut_rec = None
    if with_shutdown:
        e.run_shutdown()
        shut_rec = e.rec[n_start:]
    return dict(name=name, Tc=tc, Pk=pk, target=target, hp=hp, desc=desc, rec=start_rec,
                shut=shut_rec, ev=ev_start, ev_all=dict(e.ev), steps=k_start, steps_all=e.k,
                nsolve=e.solver.nsolve, nevals=e.solver.nevals, nfail=e.solver.nfail,
                maxres=e.solver.maxres, cpu=time.time() - t0)


def analyse(R):
    rec, ev = R['rec'], R['ev']
    last = rec[-STEADY_WINDOW:]
    avg = {c: sum(r[2][c] for r in last) / len(last) for c in MEAS}
    final_mw = avg['MW']
    tgt_t = None
    for r in rec:
        if r[4]['breaker'] and r[2]['MW'] >= final_mw * 0.995:
            tgt_t = r[0]
            break
    st_win = [r for r in rec if ev['light_off'] <= r[0] <= ev['breaker_close']]
    pk48 = max(r[2]['T48_F'] for r in st_win)
    pk48_all = max(r[2]['T48_F'] for r in rec)
    pkT4 = max(r[3]['T4'] for r in st_win)
    minsm = min(r[3]['SM'] for r in rec if r[0] >= ev['light_off'])
    st = sim.operate(R['Tc'] + 273.15, R['Pk'] * 1e3, R['hp'], R['target'] / PREF * 1e6, None)
    ms = sim.measured(st)
    dev = max(abs(avg[c] - ms[c]) / max(abs(ms[c]), 1.0) for c in MEAS)
    tit_lim = any(r[4]['loop'] == 'tit' for r in last)
    return dict(avg=avg, final_mw=final_mw, t_target=tgt_t, pk48=pk48, pk48_all=pk48_all,
                pkT4=pkT4, minsm=minsm, sim_capped=st['capped'], sim_dev=dev, sim_meas=ms,
                tit_limited=tit_lim,
                t_idle_from_start=ev['idle'] - ev['start_cmd'],
                t_idle_from_lo=ev['idle'] - ev['light_off'],
                t_sync_from_start=ev['breaker_close'] - ev['start_cmd'],
                t_sync_from_release=ev['breaker_close'] - ev['brake_release'],
                overshoot=100.0 * (ev['pt_peak'] / NPT_SYNC - 1.0), slip=ev['slip_at_close_pct'])


def main():
    t_all = time.time()
    os.makedirs(OUTDIR, exist_ok=True)
    log_names = [n for n, _ in LOG_PLAN]
    results = []
    for i, spec in enumerate(STARTS):
        R = simulate(spec, spec[0] in log_names[:-1])
        R['A'] = analyse(R)
        R['idx'] = i + 1
        R['t0'] = START_T0 + timedelta(days=START_DAY_STEP * i)
        results.append(R)
        print('%s  %5.1f s cpu, %d steps, gas-path failures %d' % (R['name'], R['cpu'], R['steps'], R['nfail']))
    byname = {R['name']: R for R in results}

    # ------------------------------------------------------------ start files
    srows, stexact, stnoisy = [], [], []
    for R in results:
        name, t0 = R['name'], R['t0']
        rng = random.Random(NOISE_SEED0 + R['idx'])
        ex, no, it = [], [], []
        for r in R['rec']:
            ts = iso(t0 + timedelta(seconds=int(round(r[0]))))
            ex.append(fmt_meas(ts, r[2], False))
            nm = add_noise(r[2], rng)
            no.append(fmt_meas(ts, nm, True))
            it.append(internal_row(ts, r))
        hdr = ['timestamp'] + MEAS
        write_csv(os.path.join(OUTDIR, name + '.csv'), hdr, no)
        write_csv(os.path.join(OUTDIR, name + '_exact.csv'), hdr, ex)
        write_csv(os.path.join(OUTDIR, name + '_internal.csv'), [c for c, _ in INT_COLS], it)
        # steady snapshot: mean of the last STEADY_WINDOW rows of the noisy and exact files
        for rows, dst, noisy in ((no, stnoisy, True), (ex, stexact, False)):
            last = [ln.split(',') for ln in rows[-STEADY_WINDOW:]]
            mean = {c: sum(float(v[j + 1]) for v in last) / len(last) for j, c in enumerate(MEAS)}
            tmid = t0 + timedelta(seconds=int(round(R['rec'][-STEADY_WINDOW // 2][0])))
            dst.append(fmt_meas(iso(tmid), mean, noisy) + ',' + name + ',' +
                       ','.join('%.2f' % R['hp'][k] for k in HEALTH_KEYS))
        A, ev = R['A'], R['ev']

        def at(tsec):
            return iso(t0 + timedelta(seconds=int(round(tsec)))) if tsec is not None else ''
        t_lo, t_idle, t_brk = ev['light_off'], ev['idle'], ev['breaker_close']
        srows.append(','.join([
            name, R['desc'].replace(',', ';'), iso(t0), '%.2f' % R['Tc'], '%.2f' % R['Pk'],
            '%.2f' % R['target'], '%.1f' % (100 * R['target'] / D['MW']),
            '%.4f' % A['final_mw'], 'yes' if A['tit_limited'] else 'no'] +
            ['%.2f' % R['hp'][k] for k in HEALTH_KEYS] + [
            '%.1f' % ev['start_cmd'], '%.1f' % t_lo, '%.1f' % t_idle, '%.1f' % ev['brake_release'],
            '%.1f' % t_brk, '%d' % A['t_target'], at(ev['start_cmd']), at(t_lo), at(t_idle),
            at(t_brk), at(A['t_target']), '%.1f' % A['pk48'], '%.1f' % A['pk48_all'],
            '%.4f' % A['overshoot'], '%.4f' % A['slip'], '%d' % (NOISE_SEED0 + R['idx']),
            '%d' % len(R['rec'])]))
    s_hdr = ['file', 'description', 'file_start', 'T_amb_C', 'P_amb_kPa', 'target_MW', 'target_pct',
             'final_MW', 'tit_limited'] + ['true_' + k for k in HEALTH_KEYS] + [
        't_start_cmd_s', 't_lightoff_s', 't_idle_s', 't_pt_release_s', 't_breaker_close_s',
        't_target_reached_s', 'start_cmd_time', 'lightoff_time', 'idle_time', 'breaker_close_time',
        'target_reached_time', 'peak_T48_start_F', 'peak_T48_file_F', 'pt_overshoot_pct',
        'slip_at_close_pct', 'noise_seed', 'rows']
    write_csv(os.path.join(OUTDIR, 'startups.csv'), s_hdr, srows)
    sp_hdr = ['timestamp'] + MEAS + ['group'] + ['true_' + k for k in HEALTH_KEYS]
    write_csv(os.path.join(OUTDIR, 'steady_points.csv'), sp_hdr, stnoisy)
    write_csv(os.path.join(OUTDIR, 'steady_points_exact.csv'), sp_hdr, stexact)

    # ------------------------------------------------------------ operations log
    write_log(byname)

    # ------------------------------------------------------------ robustness sweep (not written as data)
    stress = []
    for label, tc, hp, tgt in STRESS:
        e = Engine(tc + 273.15, ISO_P, hp, tgt)
        try:
            e.run_start()
            e.run_shutdown()
            ok = 'ok'
        except RuntimeError as ex:
            ok = 'FAILED (%s)' % ex
        stress.append((label, tc, tgt, ok, e.solver.nsolve, e.solver.nfail, e.ev))
        print('stress %-34s %s' % (label, ok))

    # ------------------------------------------------------------ datasheet and checks
    write_dynamics_txt(results)
    write_checks(results, stress)
    print('done in %.1f s' % (time.time() - t_all))


def write_log(byname):
    rng = random.Random(LOG_SEED)
    segs = []
    for j, (name, (hh, mm)) in enumerate(LOG_PLAN):
        R = byname[name]
        t0 = LOG_T0 + timedelta(days=j, hours=hh, minutes=mm)
        rec = R['rec'] + (R['shut'] or [])
        segs.append((t0, R, rec))
    no_rows, truth = [], []

    def emit(ts, m):
        no_rows.append(fmt_meas(iso(ts), add_noise(m, rng), True))

    prev_end, prev_amb = None, None
    for j, (t0, R, rec) in enumerate(segs):
        Ta, Pa = R['Tc'] + 273.15, R['Pk'] * 1e3
        # rest before this start, every REST_DT s
        if prev_end is None:
            ts = t0 - timedelta(seconds=LOG_PRE_REST)
            while ts < t0:
                emit(ts, rest_meas(Ta, Pa))
                ts += timedelta(seconds=REST_DT)
        else:
            ts = prev_end + timedelta(seconds=REST_DT - prev_end.second % REST_DT)
            span = (t0 - prev_end).total_seconds()
            while ts < t0:
                f = (ts - prev_end).total_seconds() / span
                w = 0.5 - 0.5 * math.cos(math.pi * f)
                emit(ts, rest_meas(prev_amb[0] + w * (Ta - prev_amb[0]), prev_amb[1] + w * (Pa - prev_amb[1])))
                ts += timedelta(seconds=REST_DT)
        for r in rec:
            emit(t0 + timedelta(seconds=int(round(r[0]))), r[2])
        last_t = int(round(rec[-1][0]))
        prev_end = t0 + timedelta(seconds=last_t)
        prev_amb = (Ta, Pa)
        ev = R['ev_all']

        def at(key):
            return iso(t0 + timedelta(seconds=int(round(ev[key])))) if key in ev else ''
        shut = R['shut'] is not None
        tgt = R['A']['t_target']
        truth.append(','.join([
            '%d' % (j + 1), R['name'], R['desc'].replace(',', ';'), iso(t0), iso(prev_end),
            '%.2f' % R['Tc'], '%.2f' % R['Pk'], '%.2f' % R['target'], '%.4f' % R['A']['final_mw']] +
            ['%.2f' % R['hp'][k] for k in HEALTH_KEYS] + [
            at('start_cmd'), at('light_off'), at('idle'), at('breaker_close'),
            iso(t0 + timedelta(seconds=tgt)),
            at('unload_start') if shut else '', at('breaker_open') if shut else '',
            at('fuel_off') if shut else '', at('at_rest') if shut else '',
            'normal shutdown' if shut else 'running at end of log']))
    hdr = ['timestamp'] + MEAS
    write_csv(os.path.join(OUTDIR, 'operations_log.csv'), hdr, no_rows)
    t_hdr = ['seq', 'source_start', 'description', 'segment_start', 'segment_end', 'T_amb_C',
             'P_amb_kPa', 'target_MW', 'final_MW'] + ['true_' + k for k in HEALTH_KEYS] + [
        'start_cmd_time', 'lightoff_time', 'idle_time', 'breaker_close_time',
        'target_reached_time', 'unload_start_time', 'breaker_open_time', 'fuel_off_time',
        'at_rest_time', 'end']
    write_csv(os.path.join(OUTDIR, 'operations_truth.csv'), t_hdr, truth)


def cold_cranking_table():
    """cold (no fuel) gas path on an ISO day, PT braked, VIGV closed, bleed open"""
    e = Engine(ISO_T, ISO_P, H(), 0.0)
    u, rows = list(e.ref_u), []
    I_prev, u_prev = None, None
    N = N_REST * NGG_DES
    for nf in (0.05, 0.10, 0.15, 0.20, 0.25, 0.30, 0.40, 0.50):
        while N < nf * NGG_DES - 1e-9:
            N = min(N + 0.01 * NGG_DES, nf * NGG_DES)
            I = e._inputs(N, 0.0, 0.0, sim.VIGV_MAX, sim.BLEED_MAX)
            u = e.solver.solve(u, I, I_prev, u_prev)
            I_prev, u_prev = I, u
        res, g = gaspath(u, I, True)
        w = N * RPM2RAD
        net = g['tau_c'] - g['tau_h'] + gg_loss_torque(w)
        rows.append((nf, g['W1'], g['PR'], g['beta'], g['eta_c'], g['r_hpt'], g['tau_c'], g['tau_h'],
                     net, net * w / 1e3, starter_curve(nf)))
    return rows


def write_dynamics_txt(results):
    L = []
    A = L.append
    A('INDEP2 two-shaft gas turbine generator set -- start-up dynamics datasheet (dyn.py)')
    A('=' * 78)
    A('Everything below is a modelling choice of dyn.py; the steady-state engine (maps,')
    A('losses, health scaling) is sim.py unchanged above the map floor.')
    A('')
    A('Rotating inertias')
    A('  Gas generator (compressor + HPT + accessory share) J_GG ...... %6.1f kg m^2' % P['J_GG'])
    A('     kinetic energy at 11 200 rpm ............................ %6.1f MJ'
      % (0.5 * P['J_GG'] * W_GG_DES ** 2 / 1e6))
    A('  PT + gearbox + generator, referred to PT speed, J_PT ........ %6.1f kg m^2' % P['J_PT'])
    A('     kinetic energy at 8 500 rpm ............................. %6.1f MJ'
      % (0.5 * P['J_PT'] * W_PT_DES ** 2 / 1e6))
    A('  Shaft equations: J dw/dt = sum of torques (explicit Euler, dt = %.2f s); the gas path is' % CTL['DT'])
    A('  quasi-steady (no volumes): flow compatibility re-solved at every step.')
    A('')
    A('Shaft losses')
    A('  GG: sim.py loss %.1f %% of design compressor power x (N/Ndes)^2 (torque ~ N), plus'
      % (100 * D['GG_LOSS']))
    A('      bearing friction %.0f N m below %.0f %% speed, faded out (smoothstep) by %.0f %%.'
      % (P['TF_GG'], 100 * P['TF_FADE'][0], 100 * P['TF_FADE'][1]))
    A('  PT train, breaker open: gearbox + generator no-load loss of sim.py at 8 500 rpm')
    A('      (%.1f kW, = shaft power for 0 MW) scaled ~ N^2 (torque ~ N), plus %.0f N m'
      % (P_NL_SYNC / 1e3, P['TF_PT']))
    A('      friction below %.0f %% speed faded out by %.0f %%.' % (100 * P['TF_FADE'][0], 100 * P['TF_FADE'][1]))
    A('  PT train, breaker closed: speed held by the grid; MW = sim.py elec_from_shaft(PT power')
    A('      - J_PT w dw/dt) (the last term only during the %.1f s pull-in after closing).' % SEQ['TAU_PULLIN'])
    A('')
    A('Starter (electric motor on a VFD, drives the GG through a clutch)')
    A('  torque limit %.0f N m up to %.0f %% GG speed, then constant power %.0f kW (torque ~ 1/N)'
      % (STARTER['TMAX'], 100 * STARTER['N_BASE'],
         STARTER['TMAX'] * STARTER['N_BASE'] * W_GG_DES / 1e3))
    A('  speed mode (crank/purge/light-off speed) : PI speed loop inside the torque limit')
    A('  assist mode (from light-off)             : full torque limit curve')
    A('  cut-out at %.0f %% GG speed, torque ramped to zero in %.0f s, then declutched'
      % (100 * SEQ['N_CUTOUT'], SEQ['T_CUTOUT_RAMP']))
    A('')
    A('Normal start sequence (times from the start command)')
    A('  1. starter on, speed reference ramped at %.1f %%/s to the purge speed %.0f %% (2 240 rpm)'
      % (SEQ['CRANK_RATE'], 100 * SEQ['N_PURGE']))
    A('  2. purge %.0f s at %.0f %%' % (SEQ['T_PURGE'], 100 * SEQ['N_PURGE']))
    A('  3. speed reference ramped down at %.1f %%/s to the light-off speed %.0f %%; ignitors on'
      % (SEQ['LIGHT_RATE'], 100 * SEQ['N_LIGHT']))
    A('  4. after %.0f s at light-off speed: fuel step to %.3f kg/s (%.0f lb/h), starter to assist'
      % (SEQ['T_IGN'], SEQ['WF_LIGHT'], kgs2lbh(SEQ['WF_LIGHT'])))
    A('  5. light-off fuel held %.0f s, then fuel control with the GG speed reference = idle'
      % SEQ['T_LIGHT_HOLD'])
    A('  6. starter cut-out at %.0f %%; idle %.0f %% = %.0f rpm (physical), "idle reached" within %.1f %%'
      % (100 * SEQ['N_CUTOUT'], 100 * SEQ['N_IDLE'], SEQ['N_IDLE'] * NGG_DES, 100 * SEQ['IDLE_BAND']))
    A('  7. warm-up %.0f s at idle with the PT brake on (PT at rest, EGT = T48)' % SEQ['T_WARM'])
    A('  8. PT brake released: the PT breaks away on the gas torque; PT speed governor on')
    A('  9. breaker closes when |slip| <= %.1f %% for %.0f s (slip = NPT/8500 - 1)'
      % (100 * SEQ['SLIP_BAND'], SEQ['T_SLIP']))
    A(' 10. load reference ramped at %.2f MW/s (electrical) to the target, then held %.0f s'
      % (SEQ['LOAD_RATE'], SEQ['T_HOLD']))
    A('  Idle is set at 58 %, a little below full-speed-no-load (FSNL needs 59-63 % GG speed')
    A('  here): at idle the free PT then settles below 8 500 rpm with no governor action.')
    A('')
    A('Normal shutdown (operations log only)')
    A('  load reference ramped down at %.2f MW/s to %.1f MW; breaker opens at <= %.2f MW;'
      % (SEQ['LOAD_RATE'], SEQ['UNLOAD_TO'], SEQ['UNLOAD_TO'] + 0.02))
    A('  GG speed reference = idle (PT free, no governor), cool-down %.0f s; fuel shut off;' % SEQ['T_COOL'])
    A('  both shafts coast to rest (gas drag + losses + friction).')
    A('')
    A('Fuel control (every %.2f s; velocity-form loops, min/max select)' % CTL['DT'])
    A('  N-dot demand = K_N (NGG_ref - NGG), K_N = %.1f 1/s, clipped to' % CTL['K_N'])
    A('     max: %s (n, %%/s of 11 200 rpm; smoothstep between points)' % (CTL['NDOT_MAX'],))
    A('     min: %.1f %%/s' % CTL['NDOT_MIN'])
    A('  N-dot loop   : Wf += %.2f (Ndot_dem - Ndot) / (%.0f %%/s per kg/s)' % (CTL['K_A'], CTL['A_EST']))
    A('  TIT limit    : Wf += %.2f (T4max - T4) / (dT4/dWf), T4max = %.3f K (sim.py cap)'
      % (CTL['K_T'], CTL['T4_MAX']))
    A('  Wf = min(N-dot loop, TIT loop), then clipped to the ratio-unit limits')
    A('     Wf/P3 <= RU_max(nc) %s (nc, kg/s per bar)' % (CTL['RU_MAX'],))
    A('     Wf/P3 >= %.3f kg/s per bar (lean blow-out)' % CTL['RU_MIN'])
    A('     during the acceleration to idle Wf >= the light-off fuel')
    A('  NGG_ref: idle during start/warm-up/cool-down; otherwise set by the outer loop:')
    A('  PT speed governor (PT brake released until breaker close):')
    A('     NGG_ref = idle + I + %.1f g (NPT_ref - NPT), dI/dt = %.2f/s g (NPT_ref - NPT) (rpm),'
      % (CTL['KP_PT'], CTL['KI_PT']))
    A('     gain schedule g = max(NPT, 2500)/8500; NGG_ref clipped to [idle, %.0f %%];'
      % (100 * CTL['NGG_MAX']))
    A('     NPT_ref ramps at %.1f %%/s, approaches 8500 (1 + %.2f %%) exponentially (tau %.0f s)'
      % (SEQ['PT_RATE'], 100 * SEQ['SYNC_BIAS'], SEQ['PT_TAU']))
    A('     and follows the PT while the PT runs ahead on idle gas power.')
    A('  MW controller (breaker closed): NGG_ref = NGG_close + I + (%.2f/k) e, dI/dt = (%.2f/s/k) e,'
      % (CTL['KP_MW'], CTL['KI_MW']))
    A('     e = MW_ref - MW, k = dMW/dNGG estimate 1.5e-3 ... 5e-3 MW/rpm (smoothstep 2-6 MW).')
    A('  Anti-windup: outer integrators frozen while a fuel limit (TIT, RU_max, N-dot max) is')
    A('  active and the error would wind them further, or NGG_ref is at a clip.')
    A('  "Base load" = 13.0 MW reference with the TIT limit: on warm days the TIT loop holds')
    A('  T4 = %.3f K and the power settles below 13 MW (as sim.py\'s cap).' % CTL['T4_MAX'])
    A('')
    A('Actuators and sensors')
    A('  VIGV and handling bleed follow sim.py\'s schedules through first-order lags (%.1f s, %.1f s)'
      % (P['TAU_VIGV'], P['TAU_BLEED']))
    A('  Thermocouples, first-order lags: CDT %.1f s, T48 rake %.1f s, EGT rake %.1f s'
      % (P['TAU_CDT'], P['TAU_T48'], P['TAU_EGT']))
    A('  Speeds, pressures, fuel flow, MW, ambient: no lag.  Historian: instantaneous 1 Hz samples.')
    A('')
    A('Below the compressor map (n < %.2f corrected)' % P['N_L'])
    A('  s = ln(n / %.2f); w(n,beta) = w(%.2f,beta) exp(Gw), (PR-1)(n,beta) = (PR-1)(%.2f,beta) exp(Gq)'
      % (P['N_L'], P['N_L'], P['N_L']))
    A('  Gw = %.0f s + (k_w - %.0f) s0 (e^(s/s0) - 1), Gq = %.0f s + (2.3 - %.0f) s0 (e^(s/s0) - 1), s0 = %.2f'
      % (P['KW_LOW'], P['KW_LOW'], P['KQ_LOW'], P['KQ_LOW'], P['S0']))
    A('  k_w = local d ln w / d ln n of the map at %.2f (2.6-2.7), so flow and pressure rise are' % P['N_L'])
    A('  C1-continuous at the floor and tend to similarity (w ~ n, PR-1 ~ n^2) towards standstill.')
    A('  Efficiency: e = e(%.2f,beta) [%.2f + %.2f exp(c (n - %.2f))], c from the map slope (C1),'
      % (P['N_L'], P['EFF_FLOOR'], 1 - P['EFF_FLOOR'], P['N_L']))
    A('  i.e. falling towards %.0f %% of its value at the floor (55-60 %% of it at standstill).'
      % (100 * P['EFF_FLOOR']))
    A('  Beyond the choke end (beta > 1): w = w_choke (1 + %.2f (beta-1)^2), PR keeps falling along' % CHOKE_SLOPE)
    A('  sim.py\'s line (rear stages choked); cold cranking runs there (beta ~ 1.2).')
    A('  Turbines: sim.py efficiency parabola in nu/nu_opt above %.1f; below it a cubic through 0 with'
      % P['R_L'])
    A('  C1 join and a stall torque %.1f x the torque at nu_opt, so the torque stays finite at zero' % P['STALL'])
    A('  speed (PT breakaway, GG light-off).  Above nu_opt the parabola is kept: a coasting PT in a')
    A('  weak flow absorbs work (windage heating of the exhaust).')
    A('  Below %.1f %% GG speed the gas path is not solved: the cold solution at %.1f %% is scaled'
      % (100 * N_REST, 100 * N_REST))
    A('  by similarity (flows ~ N, pressure/temperature rises and torques ~ N^2).')
    A('')
    A('Cold cranking on an ISO day (no fuel, PT braked, VIGV 30 deg, bleed 6 %)')
    A('    n     W1     PR     beta   eta_c  nu/nu_opt  tau_comp  tau_hpt  drag   drag   starter')
    A('    -    kg/s    -       -      -     HPT       N m       N m      N m    kW     limit N m')
    for r in cold_cranking_table():
        A('  %4.2f %6.3f %7.4f %6.3f %6.3f %7.2f %9.1f %8.1f %7.1f %6.1f %7.0f' % r)
    A('')
    A('Numerics: gas-path unknowns beta, ln(PR_hpt-1), ln(PR_pt-1); residuals HPT and PT capacity,')
    A('exhaust pressure (scaled by the compressor pressure rise); Newton with Jacobian re-use,')
    A('tolerance %.0e, continuation in the inputs as fallback (never needed).  dt = %.2f s.' % (GP_TOL, CTL['DT']))
    with open(os.path.join(HERE, 'dynamics.txt'), 'w') as fh:
        fh.write('\n'.join(L) + '\n')


STRESS = [
    ('heavy mixed degradation, 45 C', 45.0, H(D_GC=5.0, D_EC=2.5, D_GT=2.5, D_ET=3.0, D_GP=-2.0, D_EP=2.5), 13.0),
    ('heavy mixed degradation, -15 C', -15.0, H(D_GC=5.0, D_EC=2.5, D_GT=2.5, D_ET=3.0, D_GP=-2.0, D_EP=2.5), 13.0),
    ('erosion mix, 45 C, 5 MW', 45.0, H(D_EC=1.0, D_GT=-2.5, D_ET=3.0, D_GP=1.0), 5.0),
    ('healthy, -15 C, base', -15.0, H(), 13.0),
]


def write_checks(results, stress):
    L = []
    L.append('dyn.py checks: start-ups of the indep2 unit')
    L.append('=' * 78)
    L.append('start     day(C,kPa)    target  final   TIT  pkT48st pkT48  idle  idle  sync  sync  PT ovs  slip@close  tgt   max|dev|')
    L.append('                        MW      MW      lim  F       F      s*    s**   s*    s***  %       %           s*    vs sim.py')
    for R in results:
        A = R['A']
        L.append('%-9s %5.1f,%6.2f  %6.2f %7.3f  %-4s %6.0f %6.0f %5.0f %5.0f %5.0f %5.0f %+7.3f %+9.3f   %5.0f  %.1e'
                 % (R['name'], R['Tc'], R['Pk'], R['target'], A['final_mw'],
                    'yes' if A['tit_limited'] else 'no', A['pk48'], A['pk48_all'],
                    A['t_idle_from_start'], A['t_idle_from_lo'], A['t_sync_from_start'],
                    A['t_sync_from_release'], A['overshoot'], A['slip'],
                    A['t_target'] - R['ev']['start_cmd'], A['sim_dev']))
    L.append('  * from the start command   ** from light-off   *** from PT brake release')
    L.append('  pkT48st: peak T48 (lagged thermocouple) from light-off to breaker close;'
             ' pkT48: whole file')
    L.append('  max|dev|: largest relative difference of the last-5-min mean (exact file) from')
    L.append('  sim.operate() at the same day, health and load target (TIT cap included)')
    L.append('')
    tot = sum(R['nsolve'] for R in results)
    L.append('gas-path solves %d, failures %d, max final residual %.1e, evaluations %d'
             % (tot, sum(R['nfail'] for R in results), max(R['maxres'] for R in results),
                sum(R['nevals'] for R in results)))
    L.append('')
    L.append('robustness sweep (start + normal shutdown, 101.325 kPa; health as sim.py checks.txt sec. 4):')
    for label, tc, tgt, ok, ns, nf, ev in stress:
        L.append('  %-34s target %5.1f MW: %s, %d solves, %d failures, idle %s s, breaker %s s, at rest %s s'
                 % (label, tgt, ok, ns, nf, '%.0f' % ev['idle'] if 'idle' in ev else '-',
                    '%.0f' % ev['breaker_close'] if 'breaker_close' in ev else '-',
                    '%.0f' % ev['at_rest'] if 'at_rest' in ev else '-'))
    with open(os.path.join(OUTDIR, 'checks_dyn.txt'), 'w') as fh:
        fh.write('\n'.join(L) + '\n')
    print('\n'.join(L))


if __name__ == '__main__':
    main()
