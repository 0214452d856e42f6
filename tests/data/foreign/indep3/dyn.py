#!/usr/bin/env python3
# -*- coding: utf-8 -*-
"""
indep3 / dyn.py -- start-up and operations transients of the MGT-25 marine two-shaft engine.

Builds on sim.py (the steady model in this folder): same gas properties, same compressor map
inside its range, same turbine flow/efficiency laws, same losses, same combinator and propeller
law, same health convention.  Adds what a start-up needs:

  * two shaft inertias (GG; PT + gearbox + shafting + propeller referred to PT speed),
  * a quasi-steady gas path solved every time step with the shaft equations made implicit
    (backward Euler): unknowns NGG, NPT, beta, T4, PR_HPT, PR_PT; inputs fuel flow, VSV and
    bleed positions (lagging actuators), pitch, starter torque, hot-section metal temperatures,
  * a compressor map extension below the lowest speed line by similarity laws,
  * turbine efficiency at low blade-speed ratio with a stall-torque extension,
  * air-turbine starter, low-speed bearing friction, heat soak of three metal zones,
  * thermocouple lags on the logged temperatures,
  * a fuel control (start sequence, acceleration/deceleration limits, GG start governor,
    PT speed governor per the combinator, T54 limiter with pitch-reduction load control),
  * a bridge lever moved along ramps.

Run:  python3 dyn.py     (Python 3 standard library only, deterministic)
Writes into ./startups/ : start_NN.csv, start_NN_exact.csv, start_NN_internal.csv, startups.csv,
operations_log.csv, operations_truth.csv, operations_voyages.csv, checks_dyn.txt; and
./dynamics.txt (vendor-style note of the dynamic parameters).
"""
import math
import os
import random
import sys
import time
import datetime

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import sim  # noqa: E402  (the steady model; importing it runs nothing)

T_START = time.time()
OUTDIR = os.path.join(HERE, 'startups')

sim.size_design()
sim.build_iso_line()
DES = sim.DES
AIR = sim.AIR
TREF, PREF = sim.TREF, sim.PREF
NGG_D, NPT_D = sim.NGG_D, sim.NPT_D
WG_D = NGG_D * math.pi / 30.0       # rad/s at 100 % NGG
WP_D = NPT_D * math.pi / 30.0       # rad/s at 100 % NPT
LN_PRH_D = math.log(DES['PRh'])
LN_PRP_D = math.log(DES['PRp'])

# =============================================================================
# 0. DYNAMIC PARAMETERS (our choices; listed again in dynamics.txt)
# =============================================================================
# --- inertias
J_GG = 16.0        # kg m2  GG rotor: 16-stage compressor + 2-stage HPT + accessory drive referred
J_PTR = 22.0       # kg m2  PT rotor (6 stages), upstream of the torque meter
J_DRV = 95.0       # kg m2  reduction gear + shafting + CPP incl. entrained water, referred to PT speed
J_PT = J_PTR + J_DRV

# --- low-speed bearing friction / breakaway (faded out above 20 % NGG and 10 % NPT; above that
#     the running loss laws of sim.py apply unchanged, so the steady points are not disturbed)
QF_GG0, NF_GG = 20.0, 0.20     # N m at standstill, fade-out speed (fraction of NGG_D)
QF_PT0, NF_PT = 350.0, 0.10    # N m (referred to PT), fade-out speed (fraction of NPT_D)

# --- air-turbine starter on the accessory gearbox, torque at the GG shaft
ST_Q0 = 2400.0     # N m stall torque (full air)
ST_NRUN = 0.47     # runaway speed as a fraction of NGG_D (torque falls linearly to zero there)
ST_CUTOUT = 0.40   # starter air valve closes and the sprag clutch over-runs above 40 % NGG
ST_RAMP = 12.0     # s: the starter air valve opens along a ramp (limits the cranking torque jerk)
Q_BRAKE = 2.0e4    # N m holding torque of the shaft brake (applied at standstill, released at idle)

# --- compressor map extension below the lowest speed line
N_LOW = 0.45       # lowest speed line of the analytic map used by sim.py (its domain limit)
X_SIM = 0.2857     # similarity exponent: (PR^x - 1) ~ N^2  (work coefficient constant)
A_SURGE = 2.0     # surge-line flow ~ N^A_SURGE below the lowest line (lines widen at low speed)
ETA_LOW_K = 0.35   # efficiency falls as eta_L*(1 - k(1 - N/N_L)^2) below the lowest line

# --- turbine stall-torque extension below blade-speed ratio NU_STALL (C1 match to sim's parabola)
NU_STALL_H = 0.60
NU_STALL_P = 0.60

# --- combustion efficiency at very high loading (light-off): the loss of sim.py is kept as long
#     as it is below ETA_B_SAT0 and then saturates smoothly towards ETA_B_SATMAX
ETA_B_SAT0, ETA_B_SATMAX = 0.05, 0.45

# --- heat soak: three lumped metal zones (heat capacity J/K, hA at design flow W/K)
#     C: compressor rear casing / diffuser / combustor casing  -> acts on T3
#     H: HPT stage-2 / inter-turbine duct casing and struts     -> acts on T54
#     P: PT casing / exhaust collector                          -> acts on T8
ZONES = ('C', 'H', 'P')
MC = {'C': 240.0e3, 'H': 200.0e3, 'P': 320.0e3}
HA_D = {'C': 3.0e3, 'H': 4.0e3, 'P': 5.0e3}
HA_NC = {'C': 95.0, 'H': 75.0, 'P': 130.0}    # W/K natural convection to the enclosure at standstill
W_NC = 1.0                                    # kg/s: external cooling fades as exp(-W/W_NC)

# --- thermocouple and actuator lags (s)
TAU_TC = {'T3': 2.0, 'T54': 4.0, 'T8': 5.0}    # at idle flow and above
W_TC_REF, TAU_TC_STILL = 17.5, 90.0   # below W_TC_REF the probe film coefficient falls (~W^0.5): lag grows,
#                                       up to the still-air value at standstill (soak-back is seen slowly)
TAU_VSV, TAU_BLEED, TAU_WF = 0.6, 1.0, 0.15

# --- speeds below which the gas path is scaled from a reference solution (similarity)
N_MIN = 0.05


def smooth_lowspeed(n, nf):
    """Weight of the low-speed friction: 1 at standstill, 0 above nf, C1 in between."""
    if n >= nf:
        return 0.0
    s = 1.0 - n / nf
    return s * s


# =============================================================================
# 1. COMPONENTS (same equations as sim.py inside its range)
# =============================================================================
def comp_map_dyn(N, beta, th, b):
    """Scaled compressor characteristic with VSV angle th and bleed fraction b as INPUTS (the
    actuators lag their schedules).  Returns (W2c kg/s, PR, eta_is, PR_surge) before health.
    For N >= N_LOW the expressions are exactly those of sim.comp_map.  Below, similarity from the
    N_LOW line at the same beta: corrected flow ~ N, (PR^x - 1) ~ N^2 (constant work
    coefficient), efficiency decays gently (front stages stalled, rear stages windmilling)."""
    Nm = N if N >= N_LOW else N_LOW
    ws = 0.965 * Nm ** 1.75
    dw = 0.065 + 0.20 * max(0.0, 1.0 - Nm) ** 1.5
    w = ws + dw * (1.0 - beta)
    prs = 23.5 * (ws / 0.965) ** 1.35
    prm1 = prs * (1.0 - 0.45 * (1.0 - beta) ** 2)
    dn = Nm - 0.96
    eta = 0.872 - 0.30 * dn * dn - (1.5 * (Nm - 1.0) ** 2 if Nm > 1.0 else 0.0)
    db = beta - 0.62
    eta -= (0.20 if db < 0.0 else 0.12) * db * db
    w *= (1.0 - sim.VSV_KW * th) * (1.0 + sim.BLEED_FRONT * b)
    fpr = 1.0 - sim.VSV_KPR * th
    prm1 *= fpr
    prs *= fpr
    eta -= sim.VSV_KETA * th * th
    W2c = DES['sW'] * w
    PR = 1.0 + DES['sPR'] * prm1
    PRs = 1.0 + DES['sPR'] * prs
    eta_c = DES['sE'] * eta
    if N < N_LOW:
        # Boundary lines scaled from the N_LOW line.  Choke end: W ~ N, head (PR^x - 1) ~ N^2
        # (similarity: flow coefficient and work coefficient constant).  Surge line: head ~ N^2
        # too, but its flow falls as N^A_SURGE: at low speed the front stages stall at ever lower
        # flow coefficients, so the speed lines widen in flow (the sim.py lines do the same,
        # w_s ~ N^1.75 with a growing choke-side width).  Between the two lines the beta
        # interpolation has the form of sim.comp_map (flow linear in beta, parabolic PR).
        r = N / N_LOW
        fw = (1.0 - sim.VSV_KW * th) * (1.0 + sim.BLEED_FRONT * b) * DES['sW']
        Ws = fw * ws * r ** A_SURGE
        Wc = fw * (ws + dw) * r
        W2c = Wc + (Ws - Wc) * beta
        PR0 = 1.0 + DES['sPR'] * prs * (1.0 - 0.45)
        PRs = (1.0 + (PRs ** X_SIM - 1.0) * r * r) ** (1.0 / X_SIM)
        PR0 = (1.0 + (PR0 ** X_SIM - 1.0) * r * r) ** (1.0 / X_SIM)
        k = 1.0 - (PR0 - 1.0) / (PRs - 1.0)
        PR = 1.0 + (PRs - 1.0) * (1.0 - k * (1.0 - beta) ** 2)
        eta_c *= 1.0 - ETA_LOW_K * (1.0 - r) ** 2
    return W2c, PR, eta_c, PRs


def _stall_coeffs(k, nuopt, nul):
    """eta_rel(nu) = A nu + B nu^2 below nul, matching value and slope of sim's parabola there,
    so that eta -> 0 with the blade speed and torque -> a finite stall torque."""
    c = 1.0 - k * (1.0 - nuopt) ** 2
    e = (1.0 - k * (nul - nuopt) ** 2) / c
    s = -2.0 * k * (nul - nuopt) / c
    B = (s * nul - e) / (nul * nul)
    A = (e - B * nul * nul) / nul
    return A, B


STALL_H = _stall_coeffs(sim.HPT_KNU, sim.HPT_NUOPT, NU_STALL_H)
STALL_P = _stall_coeffs(sim.PT_KNU, sim.PT_NUOPT, NU_STALL_P)


def eta_rel_ext(nu, k, nuopt, nul, AB):
    if nu >= nul:
        return sim.turb_eta_rel(nu, k, nuopt)
    return AB[0] * nu + AB[1] * nu * nu


def eta_b_of(omega_rel):
    """Combustion efficiency: sim.py's loading law, saturating smoothly at very high loading."""
    L = sim.ETA_B_LOSS_D * omega_rel
    if L > ETA_B_SAT0:
        x = L - ETA_B_SAT0
        span = ETA_B_SATMAX - ETA_B_SAT0
        L = ETA_B_SAT0 + x / (1.0 + x / span)
    return 1.0 - L


def hA(z, W):
    """Gas-to-metal conductance, forced convection ~ W^0.8."""
    return HA_D[z] * (max(W, 1e-9) / DES['Wz_' + z]) ** 0.8


def soak(g, z, T_in, Tm, W, Tguess):
    """Gas stream through a heat-soak zone: exit state by the NTU/effectiveness relation
    (exit -> metal temperature as the flow goes to zero).  Returns (T_out, Q_to_gas W)."""
    if Tm is None:
        return T_in, 0.0
    h_in = g.h(T_in)
    ntu = hA(z, W) / (W * g.cp(T_in))
    eps = 1.0 - math.exp(-ntu)
    dh = eps * (g.h(Tm) - h_in)
    if dh == 0.0:
        return T_in, 0.0
    return g.T_h(h_in + dh, Tguess), W * dh


# =============================================================================
# 2. QUASI-STEADY GAS PATH + IMPLICIT SHAFT EQUATIONS
#    x = [ngg, npt, beta, T4/T4d, ln PRh / ln PRh_d, ln PRp / ln PRp_d]
# =============================================================================
class Env:
    """Inputs of one time step (everything that is not solved for)."""
    __slots__ = ('T0', 'P0', 'WF', 'th', 'b', 'sb', 'deg', 'Tm', 'dt', 'ngg0', 'npt0', 'pitch',
                 'st_on', 'st_u', 'gg_fix', 'pt_fix', 'steady')

    def __init__(self, **kw):
        self.Tm = None
        self.dt = 0.1
        self.ngg0 = self.npt0 = 0.0
        self.pitch = 0.0
        self.st_on = False
        self.st_u = 0.0
        self.gg_fix = None      # fix ngg at this value (reference solves)
        self.pt_fix = None      # fix npt (PT held by breakaway friction or reference solve)
        self.steady = False     # True: no inertia terms (steady solve)
        self.deg = (0.0,) * 6
        self.WF = 0.0
        self.sb = 0.0
        for k, v in kw.items():
            setattr(self, k, v)


def starter_torque(ngg, E):
    if not E.st_on or ngg >= ST_NRUN:
        return 0.0
    return E.st_u * ST_Q0 * (1.0 - ngg / ST_NRUN)


def prop_power(npt, pitch):
    """Same propeller law as sim.combinator: P = P_rated n^3 (Q0 + (1-Q0) pitch^1.5)."""
    return sim.SHP_D * npt ** 3 * (sim.PROP_Q0 + (1.0 - sim.PROP_Q0) * max(pitch, 0.0) ** 1.5)


def gas_path(x, E, full=False):
    ngg, npt, beta, t4r, zh, zp = x
    if not (0.0 < ngg < 1.2) or not (-0.6 < beta < 1.6) or not (-0.05 < npt < 1.3) or t4r < 0.1 \
            or zh <= 0.0 or zp <= 0.0:
        raise ValueError('out of domain')
    npt_c = max(npt, 0.0)
    dgc, dec, dgt, det, dgp, dep = E.deg
    T0, P0 = E.T0, E.P0
    T2 = T0
    N = ngg / math.sqrt(T2 / TREF)
    W2c, PR, eta_c, PRs = comp_map_dyn(N, beta, E.th, E.b)
    W2c *= (1.0 - dgc / 100.0)
    eta_c *= (1.0 - dec / 100.0)
    if PR <= 1.0 + 1e-7 or eta_c <= 0.05:
        raise ValueError('compressor out of domain')
    P2 = P0 / (1.0 + sim.K_IN * (W2c / DES['W2c']) ** 2)
    W2 = W2c * (P2 / PREF) / math.sqrt(T2 / TREF)
    NGG = ngg * NGG_D
    c = sim.compressor(T2, P2, W2, PR, eta_c, E.b)
    Tm = E.Tm
    # heat soak, zone C (diffuser / combustor casing): after the compressor work is done
    T3a = c['T3']
    T3, QC = soak(AIR, 'C', T3a, Tm['C'] if Tm else None, c['W3'], T3a)
    if QC != 0.0:
        c['T3'] = T3
        c['h3'] = AIR.h(T3)
    # ---- combustor + HPT (as sim.hot_section, with the saturating combustion efficiency and the
    #      stall-extended HPT efficiency)
    T4 = t4r * DES['T4']
    W3, P3 = c['W3'], c['P3']
    W_ngv, W_r1, W_s2, W_lk = W3 * sim.COOL_NGV1, W3 * sim.COOL_ROT1, W3 * sim.COOL_ST2, W3 * sim.LEAK
    W_sb = E.sb * W3                     # start/idle bleed valve, CDP air dumped overboard
    Wcc = W3 - W_ngv - W_r1 - W_s2 - W_lk - W_sb
    omega = Wcc / (P3 ** 1.75 * math.exp(T3 / 300.0))
    eta_b = eta_b_of(omega / DES['omega'])
    far = (AIR.h(T4) - AIR.h(T3)) / (eta_b * sim.LHV + sim.H_FUEL - sim.FUELB.h(T4))
    if far < -1e-4:
        raise ValueError('negative fuel')
    WFc = far * Wcc
    Wc3 = Wcc * math.sqrt(T3) / P3
    P4 = P3 * (1.0 - sim.K_CC * (Wc3 / DES['Wc3']) ** 2)
    Wa41, Wf41, T41, g41 = sim.mix([(Wcc, WFc, T4), (W_ngv, 0.0, T3)], T4 - 40.0)
    W41, P41 = Wa41 + Wf41, P4
    PRh = math.exp(zh * LN_PRH_D)
    T48s = g41.T_phi(g41.phi(T41) - g41.R * math.log(PRh), T41 * PRh ** -0.25)
    dhis_h = g41.h(T41) - g41.h(T48s)
    if dhis_h <= 0.0:
        raise ValueError('no HPT expansion')
    nu_h = ngg / math.sqrt(dhis_h / DES['dhis_h'])
    eta_h = sim.ETA_H_D * eta_rel_ext(nu_h, sim.HPT_KNU, sim.HPT_NUOPT, NU_STALL_H, STALL_H) \
        * (1.0 - det / 100.0)
    PR1 = math.sqrt(PRh)
    Tm1, dh1, _, _ = sim.expand(g41, T41, PR1, lambda d: eta_h)
    Wam, Wfm, Tm2, gm = sim.mix([(Wa41, Wf41, Tm1), (W_r1, 0.0, T3)], Tm1 - 20.0)
    T45, dh2, _, _ = sim.expand(gm, Tm2, PR1, lambda d: eta_h)
    P_hpt = W41 * dh1 + (Wam + Wfm) * dh2
    Wa48, Wf48, T48, g48 = sim.mix([(Wam, Wfm, T45), (W_s2, 0.0, T3)], T45 - 20.0)
    P48 = P41 / PRh
    # HPT flow capacity (sim.cycle residual 1)
    Nh = (NGG / math.sqrt(T41)) / DES['Nh']
    fc41 = W41 * math.sqrt(T41) / P41
    r1 = fc41 / (DES['FC41'] * sim.hpt_fc(PRh, Nh, DES['PRh']) * (1.0 - dgt / 100.0)) - 1.0
    # ---- inter-turbine duct, heat soak zone H
    W48 = Wa48 + Wf48
    Wc48 = W48 * math.sqrt(T48) / P48
    P54 = P48 * (1.0 - sim.K_ITD * (Wc48 / DES['Wc48']) ** 2)
    T54, QH = soak(g48, 'H', T48, Tm['H'] if Tm else None, W48, T48)
    # ---- power turbine
    NPT = npt_c * NPT_D
    Np = (NPT / math.sqrt(T54)) / DES['Np']
    fc54 = W48 * math.sqrt(T54) / P54
    PRp = math.exp(zp * LN_PRP_D)
    r2 = fc54 / (DES['FC54'] * sim.pt_fc(PRp, Np, DES['PRp']) * (1.0 - dgp / 100.0)) - 1.0
    h54 = g48.h(T54)
    T5s = g48.T_phi(g48.phi(T54) - g48.R * math.log(PRp), T54 * PRp ** -0.25)
    dhis_p = h54 - g48.h(T5s)
    if dhis_p <= 0.0:
        raise ValueError('no PT expansion')
    sq = math.sqrt(dhis_p / DES['dhis_p'])
    nu_p = npt_c / sq
    ep = sim.ETA_P_D * (1.0 - dep / 100.0)
    if nu_p >= NU_STALL_P:
        eta_p = ep * sim.turb_eta_rel(nu_p, sim.PT_KNU, sim.PT_NUOPT)
        wsp = eta_p * dhis_p                       # specific PT work, J/kg
        Q_pt = W48 * wsp / (npt_c * WP_D)          # aero torque, N m
    else:
        # stall-torque extension: eta = A nu + B nu^2 -> torque finite at zero speed
        A, B = STALL_P
        eta_p = ep * (A * nu_p + B * nu_p * nu_p)
        wsp = eta_p * dhis_p
        Q_pt = W48 * ep * (A + B * nu_p) * dhis_p / sq / WP_D
    T5a = g48.T_h(h54 - wsp, T5s)
    P_pt = W48 * wsp
    # heat soak zone P (PT casing / exhaust collector): T8 = PT exit after the zone
    T5, QP = soak(g48, 'P', T5a, Tm['P'] if Tm else None, W48, T5a)
    P5 = P54 / PRp
    Wc5 = W48 * math.sqrt(T5) / P0
    P5req = P0 * (1.0 + sim.K_EX * (Wc5 / DES['Wc5']) ** 2)
    r3 = P5 / P5req - 1.0
    # ---- fuel
    r4 = (WFc - E.WF) / (E.WF + 0.05)
    # ---- shafts (torques, N m)
    wg = ngg * WG_D
    Q_hpt = P_hpt / wg
    Q_comp = c['Pcomp'] / wg
    Q_lgg = sim.MECH_GG * Q_hpt + sim.P_ACC_D * ngg * ngg / WG_D       # = sim.gg_losses / omega
    Q_st = starter_torque(ngg, E)
    Q_fgg = QF_GG0 * smooth_lowspeed(ngg, NF_GG)
    Q_net_gg = Q_hpt - Q_lgg - Q_comp + Q_st - Q_fgg
    Q_lpt = sim.MECH_PT * Q_pt + sim.P_PTLOSS_D * npt_c / WP_D          # = sim.pt_losses / omega
    P_prop = prop_power(npt_c, E.pitch)
    Q_prop = P_prop / (npt_c * WP_D) if npt_c > 0.0 else 0.0
    Q_fpt = QF_PT0 * smooth_lowspeed(npt_c, NF_PT)
    Q_net_pt = Q_pt - Q_lpt - Q_prop - Q_fpt
    if E.steady:
        a_gg = a_pt = 0.0
    else:
        a_gg = (ngg - E.ngg0) * WG_D / E.dt
        a_pt = (npt - E.npt0) * WP_D / E.dt
    if E.gg_fix is not None:
        r5 = ngg - E.gg_fix
    else:
        r5 = (Q_net_gg - J_GG * a_gg) / 4.0e4
    if E.pt_fix is not None:
        r6 = npt - E.pt_fix
    else:
        r6 = (Q_net_pt - J_PT * a_pt) / 6.6e4
    r = [r1, r2, r3, r4, r5, r6]
    if not full:
        return r
    # ---- full state
    SHP = (Q_pt - Q_lpt - J_PTR * a_pt) * npt_c * WP_D                  # torque-meter power
    E_in = W2 * AIR.h(T2) + WFc * (eta_b * sim.LHV + sim.H_FUEL) + QC + QH + QP
    P_lgg = Q_lgg * wg
    # energy: everything the gas brings in = exhaust + overboard air + net shaft work taken out
    E_out = (sim.stream_H(Wa48, Wf48, T5) + c['Wb'] * c['h25'] + (W_lk + W_sb) * c['h3']
             + P_hpt - c['Pcomp'] + P_pt)
    st = dict(
        T0=T0, P0=P0, T2=T2, P2=P2, N=N, ngg=ngg, npt=npt_c, NGG=NGG, NPT=NPT, beta=beta,
        vsv=E.th, bleed=E.b, W2=W2, W2c=W2c, PR=PR, eta_c=eta_c, PRsurge=PRs,
        SM=(PRs / PR - 1.0) * 100.0, SMr=(PRs - PR) / (PR - 1.0) * 100.0, T3=T3, T3a=T3a, P3=P3, W3=W3, Wbleed=c['Wb'], T25=c['T25'],
        Wcc=Wcc, eta_b=eta_b, far=far, WF=WFc, T4=T4, P4=P4, T41=T41, W41=W41, PRh=PRh, eta_h=eta_h,
        nu_h=nu_h, T48=T48, P48=P48, W48=W48, T54=T54, P54=P54, PRp=PRp, eta_p=eta_p, nu_p=nu_p,
        T5=T5, T5a=T5a, P5=P5, W5=W48, Pcomp=c['Pcomp'], Phpt=P_hpt, Ppt=P_pt, P_lgg=P_lgg,
        P_lpt=Q_lpt * npt_c * WP_D, SHP=SHP, Pprop=P_prop, Q_st=Q_st, P_st=Q_st * wg,
        Q_net_gg=Q_net_gg, Q_net_pt=Q_net_pt, Q_fgg=Q_fgg, Q_fpt=Q_fpt, QC=QC, QH=QH, QP=QP,
        Q_pt=Q_pt, Q_prop=Q_prop, e_close=(E_in - E_out) / max(WFc * sim.LHV, 1e5), res=max(abs(v) for v in r))
    return r, st


# design-flow references of the heat-soak zones
def _zone_refs():
    x = [1.0, 1.0, sim.BETA_D, 1.0, 1.0, 1.0]
    E = Env(T0=sim.ISO_T0, P0=sim.ISO_P0, th=0.0, b=0.0, steady=True)
    DES['Wz_C'] = DES['Wz_H'] = DES['Wz_P'] = 70.0
    r, st = gas_path(x, E, full=True)
    DES['Wz_C'], DES['Wz_H'], DES['Wz_P'] = st['W3'], st['W48'], st['W48']


_zone_refs()


# =============================================================================
# 3. NEWTON SOLVERS
# =============================================================================
STATS = {'evals': 0, 'jac': 0, 'steps': 0}


def _inverse(A):
    n = len(A)
    M = [row[:] + [1.0 if i == j else 0.0 for j in range(n)] for i, row in enumerate(A)]
    for k in range(n):
        p = max(range(k, n), key=lambda i: abs(M[i][k]))
        if abs(M[p][k]) < 1e-300:
            raise ZeroDivisionError('singular Jacobian')
        M[k], M[p] = M[p], M[k]
        piv = M[k][k]
        M[k] = [v / piv for v in M[k]]
        for i in range(n):
            if i != k:
                f = M[i][k]
                if f != 0.0:
                    Mi, Mk = M[i], M[k]
                    M[i] = [a - f * b for a, b in zip(Mi, Mk)]
    return [row[n:] for row in M]


def _ev(fun, x):
    STATS['evals'] += 1
    try:
        return fun(x)
    except (ValueError, ZeroDivisionError, OverflowError):
        return None


def fd_jacobian(fun, x, r):
    n = len(x)
    J = [[0.0] * n for _ in range(n)]
    STATS['jac'] += 1
    for j in range(n):
        h = 1e-7 * max(1.0, abs(x[j])) if j != 4 and j != 5 else 1e-7 * max(0.02, abs(x[j]))
        xp = x[:]
        xp[j] += h
        rp = _ev(fun, xp)
        if rp is None:
            xp[j] = x[j] - h
            rp = _ev(fun, xp)
            if rp is None:
                raise ValueError('jacobian failed')
            h = -h
        for i in range(n):
            J[i][j] = (rp[i] - r[i]) / h
    return J


def step_limit(x, dx):
    """Per-variable step limits: absolute for speeds, beta, T4; relative for the log-PRs
    (they go to zero with the speed)."""
    s = 1.0
    lim = [0.05, 0.05, 0.25, 0.10, None, None]
    for i in range(len(x)):
        L = lim[i] if i < len(lim) else None
        if L is None:
            L = 0.5 * abs(x[i]) + 1e-4
        if abs(dx[i]) > L:
            s = min(s, L / abs(dx[i]))
    return s


class Solver:
    """Chord-Newton with a stored inverse Jacobian, refreshed when convergence slows.
    Time steps are small, so one or two cheap iterations usually suffice."""

    def __init__(self, tol=1e-10):
        self.Jinv = None
        self.tol = tol

    def solve(self, fun, x0, maxit=40):
        x = list(x0)
        r = _ev(fun, x)
        if r is None:
            raise ValueError('initial point invalid')
        nr = max(abs(v) for v in r)
        fresh = False
        for it in range(maxit):
            if nr < self.tol:
                return x, r
            if self.Jinv is None:
                self.Jinv = _inverse(fd_jacobian(fun, x, r))
                fresh = True
            dx = [-sum(a * b for a, b in zip(row, r)) for row in self.Jinv]
            alpha = step_limit(x, dx)
            ok = False
            for _ in range(12):
                xn = [a + alpha * b for a, b in zip(x, dx)]
                rn = _ev(fun, xn)
                if rn is not None:
                    nrn = max(abs(v) for v in rn)
                    if nrn < 0.5 * nr or (fresh and nrn < nr) or nrn < self.tol:
                        ok = True
                        break
                if not fresh:
                    break
                alpha *= 0.5
            if not ok:
                if fresh:
                    raise ValueError('newton stalled (|r|=%.3e)' % nr)
                self.Jinv = None          # stale Jacobian: refresh and retry
                continue
            x, r, nr = xn, rn, nrn
            fresh = False
        raise ValueError('newton: no convergence (|r|=%.3e)' % nr)


def solve_steady_pt(E, npt, x0, tol=1e-11, sched=False):
    """Steady operating point with the PT speed held (governor) and fuel flow free:
    the GG torque balance and the PT torque balance (SHP = propeller power) are satisfied.
    sched=True: VSV and bleed sit exactly on their schedules (settled actuators)."""
    E.steady = True
    E.pt_fix = None

    def fun(y):
        E.WF = y[5]
        if sched:
            nc = y[0] / math.sqrt(E.T0 / TREF)
            E.th, E.b = sim.vsv_angle(nc), sim.bleed_frac(nc)
        return gas_path([y[0], npt, y[1], y[2], y[3], y[4]], E)
    S = Solver(tol)
    y0 = [x0[0], x0[2], x0[3], x0[4], x0[5], E.WF]
    y, r = S.solve(fun, y0, maxit=80)
    E.WF = y[5]
    x = [y[0], npt, y[1], y[2], y[3], y[4]]
    return x, gas_path(x, E, full=True)[1]


# =============================================================================
# 4. CONTROL SYSTEM, SEQUENCER, PROPELLER PITCH
# =============================================================================
PURGE_N = 0.22             # purge and light-off speed, fraction of NGG_D (2090 rpm)
PURGE_S = 45.0             # s purge (about five volume changes of intake/engine/uptake)
WF_LIGHT = 200.0 / 3600.0  # kg/s light-off fuel flow
LIGHT_DT = 40.0            # K: light-off declared when the T54 harness rises this much
NDOT_START = 0.0075        # 1/s: scheduled start acceleration of the GG (0.75 %/s)
NGG_GI = 0.46              # ground-idle cap of the GG start governor (4370 rpm)
WARMUP_COLD = 300.0        # s warm-up at idle before the bridge may move the lever
WARMUP_HOT = 180.0         # s after a hot restart
WF_MIN_LIT = 110.0 / 3600.0  # kg/s minimum fuel while lit (flame stability)
# acceleration / deceleration limits as fuel-to-P3 ratios ("ratio units", kg/h per kPa) on Nc
RU_ACC_N = [0.0, 0.30, 0.45, 0.60, 0.80, 1.00, 1.10]
RU_ACC = [2.10, 2.10, 2.30, 2.80, 3.10, 3.30, 3.30]
RU_DEC = 0.75
# governor gains (velocity-form PI, min/max select, so no integrator wind-up)
KP_PT, KI_PT = 3.0, 1.0        # PT speed governor, on relative speed error, scaled by load
KP_GG, KI_GG = 0.3, 0.12       # GG speed governor (idle cap / NGG max), per 1 % speed error
ETA_FF = (0.26, 0.22)          # marginal thermal efficiency used by the lever feed-forward:
#                                0.26 near idle rising to 0.48 above 60 % power
KP_ND, KI_ND = 0.25, 1.2       # start Ndot governor, kg/s per (1/s) and per (1/s)/s
KP_T54, KI_T54 = 0.6, 0.12     # T54 limiter, relative fuel per 100 K and per 100 K s
KP_PURGE, KI_PURGE = 25.0, 6.0  # starter air valve holding purge speed
PITCH_RATE, TAU_PITCH = 0.04, 0.8   # CPP hydraulics: 4 %/s rate limit, 0.8 s lag
K_PITCH_RED = 0.02             # load control: pitch reduction rate per 1 % PT under-speed, 1/s
T54_LIM = DES['T54_MAX']
NGG_LIM = sim.NGG_MAX / NGG_D


def ru_acc(nc):
    return sim.interp(nc, RU_ACC_N, RU_ACC)


def ndot_schedule(ngg):
    """Start acceleration schedule: gentle at light-off, scheduled rate in the middle."""
    return NDOT_START * min(1.0, 0.4 + 0.6 * max(0.0, ngg - PURGE_N) / 0.05)


# =============================================================================
# 5. THE ENGINE (state, one time step, sequencer, logging)
# =============================================================================
def standstill_state(T0, P0, Tm):
    """Nothing flows: pressures ambient, the gas in each heat-soak zone at its metal temperature."""
    return dict(T0=T0, P0=P0, T2=T0, P2=P0, N=0.0, ngg=0.0, npt=0.0, NGG=0.0, NPT=0.0, beta=0.0,
                W2=0.0, W2c=0.0, PR=1.0, eta_c=0.0, PRsurge=1.0, SM=float('nan'), SMr=float('nan'), T3=Tm['C'], T3a=T0,
                P3=P0, W3=0.0, Wbleed=0.0, Wcc=0.0, eta_b=0.0, far=0.0, WF=0.0, T4=Tm['C'], P4=P0,
                T41=Tm['H'], W41=0.0, PRh=1.0, eta_h=0.0, nu_h=0.0, T48=Tm['H'], P48=P0, W48=0.0,
                T54=Tm['H'], P54=P0, PRp=1.0, eta_p=0.0, nu_p=0.0, T5=Tm['P'], T5a=Tm['P'], P5=P0,
                W5=0.0, Pcomp=0.0, Phpt=0.0, Ppt=0.0, P_lgg=0.0, P_lpt=0.0, SHP=0.0, Pprop=0.0,
                Q_st=0.0, P_st=0.0, Q_net_gg=0.0, Q_net_pt=0.0, Q_fgg=0.0, Q_fpt=0.0, QC=0.0, QH=0.0,
                QP=0.0, Q_pt=0.0, Q_prop=0.0, e_close=0.0, res=0.0, vsv=sim.VSV_MAX, bleed=sim.BLEED_MAX,
                H_out=0.0, H_in=0.0)


class Engine:
    def __init__(self, amb, deg, name=''):
        self.amb = amb                  # function t -> (T0 K, P0 kPa)
        self.deg = tuple(float(v) for v in deg)
        self.name = name
        self.k = 0                      # step counter; time = k * DT_BASE
        self.t = 0.0
        T0, P0 = amb(0.0)
        self.ngg = self.npt = 0.0
        self.gg_stuck = self.pt_stuck = True
        self.x = None
        self.solver = Solver(1e-10)
        self.lit = False
        self.WF = 0.0
        self.WFcmd = 0.0
        self.th, self.b = sim.VSV_MAX, sim.BLEED_MAX
        self.Tm = {z: T0 for z in ZONES}
        self.TC = {'T3': T0, 'T54': T0, 'T8': T0}
        self.pitch = 0.0
        self.pitch_red = 0.0
        self.brake = True
        self.lever = 0.0
        self.phase = 'standstill'       # engine sequencer phase
        self.ops = 'shutdown'           # bridge/operations phase
        self.t_ops = 0.0
        self.st_on = False
        self.st_u = 0.0
        self.st_done = False
        self.ready = False
        self.hot = False
        self.e_prev = {}
        self.loop = 'none'              # fuel loop in control
        self.p_dem_prev = None
        self.ndot = 0.0
        self.t_phase = 0.0
        self.ev = {}                    # event times
        self.refs = {}
        self.st = standstill_state(T0, P0, self.Tm)
        self.energy = dict(fuel=0.0, starter=0.0, prop=0.0, losses=0.0, exh=0.0, metal=0.0)
        self.mom = dict(gg=0.0, pt=0.0)
        self.ngg_prev = 0.0
        self.min_sm = 1e9
        self.max_beta = -1e9
        self.max_res = 0.0
        self.max_eclose = 0.0
        self.max_T54_start = 0.0

    # ------------------------------------------------------------------ events
    def event(self, name):
        if name not in self.ev:
            self.ev[name] = self.t

    def set_phase(self, ph):
        if ph != self.phase:
            self.phase = ph
            self.t_phase = self.t
            self.event(ph)

    # ------------------------------------------------------------------ commands
    def cmd_start(self):
        self.ev = {}
        self.event('start_cmd')
        self.set_phase('crank')
        self.st_on, self.st_u, self.st_done = True, 0.0, False
        self.ready = False
        self.hot = max(self.Tm['H'] - self.amb(self.t)[0], 0.0) > 60.0
        self.e_prev = {}

    def cmd_fuel_off(self):
        self.event('fuel_off')
        self.set_phase('rundown')
        self.lit = False
        self.WFcmd = 0.0
        self.ready = False

    # ------------------------------------------------------------------ control laws
    def pi(self, key, e, kp, ki, dt, gain):
        """Velocity-form PI: candidate fuel = current fuel + increment."""
        ep = self.e_prev.get(key, e)
        self.e_prev[key] = e
        return self.WF + gain * (kp * (e - ep) + ki * e * dt)

    def fuel_control(self, dt, n_set, p_set):
        st = self.st
        T0 = st['T0']
        nc = self.ngg / math.sqrt(T0 / TREF)
        P3 = st['P3']
        cands = {}
        # PT speed governor (combinator PT speed), gain scheduled on the propeller load
        load = prop_power(n_set, p_set) + 0.3e6
        g_pt = load / (0.35 * sim.LHV)
        # lever feed-forward: the change of the combinator's power demand, converted to fuel with
        # a typical marginal efficiency, is added to the governor's increment (the governor then
        # only trims); without it NPT droops ~9 % when pitch comes on at the start of a lever ramp
        p_dem = prop_power(n_set, p_set)
        eta_ff = ETA_FF[0] + ETA_FF[1] * min(1.0, p_dem / (0.6 * sim.SHP_D))
        ff = (p_dem - self.p_dem_prev) / (eta_ff * sim.LHV) if self.p_dem_prev is not None else 0.0
        self.p_dem_prev = p_dem
        if self.phase == 'run':
            cands['NPT'] = self.pi('NPT', (n_set - self.npt) / max(n_set, 0.3), KP_PT, KI_PT, dt, g_pt) + ff
        # GG speed governor: ground-idle cap during the start and warm-up, NGG max otherwise
        cap = NGG_GI if not self.ready else NGG_LIM
        cands['NGG'] = self.pi('NGG', (cap - self.ngg) / 0.01, KP_GG, KI_GG, dt, self.WF + 0.05)
        # T54 limiter (acts on the lagged thermocouple harness, as in the plant)
        cands['T54'] = self.pi('T54', (T54_LIM - self.TC['T54']) / 100.0, KP_T54, KI_T54, dt,
                               self.WF + 0.02)
        if self.phase == 'accel':
            cands['NDOT'] = self.pi('NDOT', ndot_schedule(self.ngg) - self.ndot, KP_ND, KI_ND, dt, 1.0)
        wf_acc = ru_acc(nc) * P3 / 3600.0
        wf_dec = max(RU_DEC * P3 / 3600.0, WF_MIN_LIT)
        key = min(cands, key=lambda k: cands[k])
        wf = cands[key]
        self.loop = key
        if wf > wf_acc:
            wf, self.loop = wf_acc, 'ACC'
        if wf < wf_dec:
            wf, self.loop = wf_dec, 'DEC'
        return wf

    # ------------------------------------------------------------------ sequencer
    def sequencer(self, dt):
        ph = self.phase
        t_in = self.t - self.t_phase
        if ph == 'crank':
            self.st_u = min(1.0, t_in / ST_RAMP)
            if self.ngg >= PURGE_N - 0.004:
                self.set_phase('purge')
                self.e_prev.pop('PURGE', None)
        elif ph == 'purge':
            e = PURGE_N - self.ngg
            ep = self.e_prev.get('PURGE', e)
            self.e_prev['PURGE'] = e
            self.st_u = min(1.0, max(0.0, self.st_u + KP_PURGE * (e - ep) + KI_PURGE * e * dt))
            if t_in >= PURGE_S:
                self.set_phase('ignition')
                self.T54_ign = self.TC['T54']
                self.st_u = 1.0
        elif ph == 'ignition':
            self.lit = True
            self.loop = 'LIGHTOFF'
            self.WFcmd = min(WF_LIGHT, self.WFcmd + WF_LIGHT * dt / 1.0)
            if self.TC['T54'] - self.T54_ign > LIGHT_DT:
                self.set_phase('accel')
                self.event('lightoff')
                for k in ('NPT', 'NGG', 'T54', 'NDOT'):
                    self.e_prev.pop(k, None)
        elif ph == 'accel':
            if self.ngg >= NGG_GI - 0.003:
                self.set_phase('run')
                self.event('gg_idle')
                self.brake = False          # shaft brake released at ground idle
                self.event('brake_release')
        elif ph == 'run':
            if not self.ready:
                if 'pt_at_set' in self.ev and self.t - self.ev['gg_idle'] >= (
                        WARMUP_HOT if self.hot else WARMUP_COLD):
                    self.ready = True
                    self.event('ready')
        if self.st_on and self.ngg >= ST_CUTOUT and self.phase in ('accel', 'run'):
            self.st_on = False
            self.st_u = 0.0
            self.event('starter_cutout')
        if self.phase in ('accel', 'run') and self.npt >= 0.97 * 0.60:
            self.event('pt_at_set')

    # ------------------------------------------------------------------ one time step
    def step(self, dt):
        t1 = self.t + dt
        T0, P0 = self.amb(t1)
        self.sequencer(dt)
        n_set, p_set, _ = sim.combinator(self.lever)
        # --- propeller pitch: combinator pitch less the load-control reduction, rate-limited
        if self.loop in ('T54', 'NGG') and self.ready:
            self.pitch_red = min(p_set, self.pitch_red + K_PITCH_RED * 100.0 *
                                 max(0.0, (n_set - self.npt) / n_set) * dt)
        else:
            self.pitch_red = max(0.0, self.pitch_red - 0.002 * dt)
        p_tgt = max(0.0, p_set - self.pitch_red)
        dp = (p_tgt - self.pitch) * (1.0 - math.exp(-dt / TAU_PITCH))
        dp = max(-PITCH_RATE * dt, min(PITCH_RATE * dt, dp))
        self.pitch += dp
        # --- fuel
        if self.phase in ('accel', 'run'):
            self.WFcmd = self.fuel_control(dt, n_set, p_set)
        elif self.phase in ('ignition',):
            pass
        else:
            self.WFcmd = 0.0
        self.WF += (self.WFcmd - self.WF) * (1.0 - math.exp(-dt / TAU_WF))
        if not self.lit:
            self.WF = 0.0
        # --- VSV and bleed actuators follow their corrected-speed schedules
        nc = self.ngg / math.sqrt(T0 / TREF)
        self.th += (sim.vsv_angle(nc) - self.th) * (1.0 - math.exp(-dt / TAU_VSV))
        self.b += (sim.bleed_frac(nc) - self.b) * (1.0 - math.exp(-dt / TAU_BLEED))
        ngg0 = self.ngg
        # --- gas path and shafts
        if nc < N_MIN:
            st = self.scaled_step(dt, T0, P0)
        else:
            st = self.implicit_step(dt, T0, P0)
        self.ndot = (self.ngg - ngg0) / dt
        # --- bookkeeping of energies (for the checks)
        en = self.energy
        en['fuel'] += st['WF'] * (st['eta_b'] * sim.LHV + sim.H_FUEL) * dt
        en['starter'] += st['P_st'] * dt
        en['prop'] += st['Pprop'] * dt
        en['losses'] += (st['P_lgg'] + st['P_lpt'] + st['Q_fgg'] * self.ngg * WG_D
                         + st['Q_fpt'] * self.npt * WP_D) * dt
        en['exh'] += (st['H_out'] - st['H_in']) * dt
        self.mom['gg'] += st['Q_net_gg'] * dt
        self.mom['pt'] += st['Q_net_pt'] * dt
        # --- metal temperatures (explicit; time constants are tens of seconds or more)
        W = {'C': st['W3'], 'H': st['W48'], 'P': st['W48']}
        Q = {'C': st['QC'], 'H': st['QH'], 'P': st['QP']}
        for z in ZONES:
            qext = HA_NC[z] * (self.Tm[z] - T0) * math.exp(-W[z] / W_NC)
            self.Tm[z] -= (Q[z] + qext) * dt / MC[z]
            en['metal'] += qext * dt
        # --- thermocouples
        for key, skey, wkey in (('T3', 'T3', 'W3'), ('T54', 'T54', 'W48'), ('T8', 'T5', 'W48')):
            w = st[wkey]
            if w >= W_TC_REF:
                tau = TAU_TC[key]
            elif w * TAU_TC_STILL ** 2 > W_TC_REF * TAU_TC[key] ** 2:
                tau = TAU_TC[key] * math.sqrt(W_TC_REF / w)
            else:
                tau = TAU_TC_STILL
            self.TC[key] += (st[skey] - self.TC[key]) * (1.0 - math.exp(-dt / tau))
        self.k += 1
        self.t = t1
        self.st = st
        if st['W2'] > 0.0:
            self.min_sm = min(self.min_sm, st['SMr'])
            self.max_beta = max(self.max_beta, st['beta'])
        self.max_res = max(self.max_res, st['res'])
        self.max_eclose = max(self.max_eclose, abs(st['e_close']))
        if self.phase in ('ignition', 'accel') or (self.phase == 'run' and not self.ready):
            self.max_T54_start = max(self.max_T54_start, self.TC['T54'])

    def env(self, dt, T0, P0):
        return Env(T0=T0, P0=P0, WF=self.WF, th=self.th, b=self.b, deg=self.deg, Tm=dict(self.Tm),
                   dt=dt, ngg0=self.ngg, npt0=self.npt, pitch=self.pitch, st_on=self.st_on,
                   st_u=self.st_u, pt_fix=0.0 if self.pt_stuck else None)

    def implicit_step(self, dt, T0, P0):
        E = self.env(dt, T0, P0)
        if self.x is None:
            self.x = self.ref_x(T0, P0)
        x0 = self.x[:]
        x0[0], x0[1] = self.ngg, self.npt
        fun = lambda z: gas_path(z, E)
        # leaving the scaled region with hot metal (hot restart): the cold reference guess may put
        # T4 below the (soak-heated) T3; raise the T4 guess until the gas path is defined
        for _ in range(40):
            if _ev(fun, x0) is not None:
                break
            x0[3] *= 1.05
        try:
            x, r = self.solver.solve(fun, x0)
        except ValueError:
            self.solver.Jinv = None
            x, r = self.solver.solve(fun, x0, maxit=80)
        if not self.pt_stuck and x[1] <= 0.0:
            # PT came to rest: hold it by the breakaway friction
            self.pt_stuck = True
            self.event('pt_stop')
            E.pt_fix = 0.0
            self.solver.Jinv = None
            x0[1] = 0.0
            x, r = self.solver.solve(fun, x0, maxit=80)
        r, st = gas_path(x, E, full=True)
        self.x = x
        self.ngg, self.npt = x[0], max(0.0, x[1])
        if E.pt_fix is not None:
            st['Q_net_pt'] = 0.0            # the brake / breakaway friction held the PT this step
        if self.pt_stuck:
            drive = st['Q_pt'] * (1.0 - sim.MECH_PT) - st['Q_prop']
            if drive > QF_PT0 + (Q_BRAKE if self.brake else 0.0):
                self.pt_stuck = False
                self.solver.Jinv = None
                self.event('pt_breakaway')
        self.gg_stuck = False
        st['H_in'] = st['W2'] * AIR.h(T0)
        st['H_out'] = st['W2'] * AIR.h(T0) + st['WF'] * (st['eta_b'] * sim.LHV + sim.H_FUEL) \
            + st['QC'] + st['QH'] + st['QP'] - (st['Phpt'] - st['Pcomp'] + st['Ppt']) \
            - st['e_close'] * max(st['WF'] * sim.LHV, 1e5)
        st['vsv'], st['bleed'] = self.th, self.b
        return st

    def skip(self, seconds):
        """Long standstill (hours between voyages): metal and thermocouples cool analytically
        towards the ambient at the end of the gap."""
        assert self.ngg == 0.0 and self.npt == 0.0
        t1 = self.t + seconds
        T0, P0 = self.amb(t1)
        for z in ZONES:
            self.Tm[z] = T0 + (self.Tm[z] - T0) * math.exp(-HA_NC[z] * seconds / MC[z])
        self.st = standstill_state(T0, P0, self.Tm)
        self.TC = {'T3': self.Tm['C'], 'T54': self.Tm['H'], 'T8': self.Tm['P']}
        self.t = t1

    # ------------------------------------------------------------------ low-speed region
    def ref_state(self, T0, P0):
        """Unfired solution at N = N_MIN (PT at rest, no heat soak, actuators on schedule): the
        reference for the similarity-scaled region below N_MIN (flows ~ N, pressure rises and
        temperature rises ~ N^2, torques ~ N^2)."""
        key = (round(T0, 1), round(P0, 2), self.deg)
        if key in self.refs:
            return self.refs[key]
        ngg_ref = N_MIN * math.sqrt(T0 / TREF)
        E = Env(T0=T0, P0=P0, WF=0.0, th=sim.vsv_angle(N_MIN), b=sim.bleed_frac(N_MIN), deg=self.deg,
                steady=True, gg_fix=ngg_ref, pt_fix=0.0)
        g = REF_X_ISO
        x0 = [ngg_ref, 0.0, g[2], g[3] * T0 / TREF, g[4], g[5]]
        S = Solver(1e-11)
        x, r = S.solve(lambda z: gas_path(z, E), x0, maxit=100)
        r, st = gas_path(x, E, full=True)
        ref = (ngg_ref, x, st)
        self.refs[key] = ref
        return ref

    def ref_x(self, T0, P0):
        ngg_ref, x, st = self.ref_state(T0, P0)
        return x[:]

    def scaled_step(self, dt, T0, P0):
        ngg_ref, xr, sr = self.ref_state(T0, P0)
        E = self.env(dt, T0, P0)
        s = self.ngg / ngg_ref
        s2 = s * s
        Q_gas = (sr['Q_net_gg'] + sr['Q_fgg']) * s2
        Q_st = starter_torque(self.ngg, E)
        drive = Q_gas + Q_st
        if self.ngg <= 0.0 and drive <= QF_GG0:
            ngg1 = 0.0
        else:
            ngg1 = self.ngg + dt * (drive - QF_GG0 * smooth_lowspeed(self.ngg, NF_GG)) / J_GG / WG_D
            ngg1 = max(0.0, ngg1)
            if ngg1 == 0.0 and 'gg_stop' not in self.ev and self.phase == 'rundown':
                self.event('gg_stop')
        # PT: the cold flow at these speeds only gives a weak stall torque
        Q_ptg = sr['Q_pt'] * s2 if self.npt < 0.02 else 0.0
        Q_prop = prop_power(self.npt, self.pitch) / (self.npt * WP_D) if self.npt > 0.0 else 0.0
        drive_p = Q_ptg * (1.0 - sim.MECH_PT) - Q_prop
        if self.pt_stuck and drive_p <= QF_PT0 + (Q_BRAKE if self.brake else 0.0):
            npt1 = 0.0
        else:
            self.pt_stuck = False
            Q_l = sim.MECH_PT * Q_ptg + sim.P_PTLOSS_D * self.npt / WP_D
            npt1 = self.npt + dt * (Q_ptg - Q_l - Q_prop - QF_PT0 * smooth_lowspeed(self.npt, NF_PT)) \
                / J_PT / WP_D
            if npt1 <= 0.0:
                npt1 = 0.0
                self.pt_stuck = True
                self.event('pt_stop')
        a_pt = (npt1 - self.npt) * WP_D / dt
        s1 = ngg1 / ngg_ref
        self.ngg_prev = self.ngg
        self.ngg, self.npt = ngg1, npt1
        self.x = None if ngg1 == 0.0 else [ngg1, npt1] + xr[2:]
        if ngg1 == 0.0:
            self.gg_stuck = True
        st = self.scaled_state(sr, s1, T0, P0)
        st['ngg'], st['npt'] = ngg1, npt1
        st['Q_net_gg'] = (ngg1 - self.ngg_prev) * WG_D * J_GG / dt
        st['Q_net_pt'] = a_pt * J_PT
        st['NGG'], st['NPT'] = ngg1 * NGG_D, npt1 * NPT_D
        st['Q_st'] = starter_torque(ngg1, E)
        st['P_st'] = st['Q_st'] * ngg1 * WG_D
        st['Q_fgg'] = QF_GG0 * smooth_lowspeed(ngg1, NF_GG) if ngg1 > 0 else 0.0
        st['Q_fpt'] = QF_PT0 * smooth_lowspeed(npt1, NF_PT) if npt1 > 0 else 0.0
        st['Pprop'] = prop_power(npt1, self.pitch)
        st['P_lpt'] = sim.P_PTLOSS_D * npt1 ** 2
        Qpt = sr['Q_pt'] * s1 * s1 if npt1 < 0.02 else 0.0
        st['Q_pt'] = Qpt
        st['Ppt'] = Qpt * npt1 * WP_D
        st['SHP'] = (Qpt * (1 - sim.MECH_PT) - sim.P_PTLOSS_D * npt1 / WP_D - J_PTR * a_pt) * npt1 * WP_D
        st['vsv'], st['bleed'] = self.th, self.b
        return st

    def scaled_state(self, sr, s, T0, P0):
        s2 = s * s
        st = dict(sr)
        dT = T0 - sr['T0']
        for k in ('P2', 'P3', 'P4', 'P48', 'P54', 'P5'):
            st[k] = P0 + (sr[k] - sr['P0']) * s2
        for k in ('T3a', 'T4', 'T41', 'T48', 'T5a'):
            st[k] = T0 + (sr[k] + dT - T0) * s2
        for k in ('W2', 'W2c', 'W3', 'Wbleed', 'Wcc', 'W41', 'W48', 'W5'):
            st[k] = sr[k] * s
        for k in ('Pcomp', 'Phpt', 'Ppt', 'P_lgg'):
            st[k] = sr[k] * s2 * s
        for k in ('Q_net_gg', 'Q_pt'):
            st[k] = sr[k] * s2
        st['PR'] = st['P3'] / st['P2'] if st['P2'] > 0 else 1.0
        st['PRsurge'] = 1.0 + (sr['PRsurge'] - 1.0) * s2
        st['SM'] = (st['PRsurge'] / st['PR'] - 1.0) * 100.0 if s > 0 else float('nan')
        st['SMr'] = sr['SMr'] if s > 0 else float('nan')
        st['T0'], st['P0'], st['T2'] = T0, P0, T0
        # heat soak with the actual metal: at these flows the gas leaves at metal temperature
        if s > 0.0:
            st['T3'], st['QC'] = soak(AIR, 'C', st['T3a'], self.Tm['C'], st['W3'], st['T3a'])
            st['T54'], st['QH'] = soak(AIR, 'H', st['T48'], self.Tm['H'], st['W48'], st['T48'])
            st['T5'], st['QP'] = soak(AIR, 'P', st['T5a'], self.Tm['P'], st['W48'], st['T5a'])
        else:
            z = standstill_state(T0, P0, self.Tm)
            st.update(z)
        st['WF'] = 0.0
        st['far'] = 0.0
        st['e_close'] = 0.0
        st['res'] = 0.0
        st['H_in'] = st['W2'] * AIR.h(T0)
        st['H_out'] = st['H_in'] + st['QC'] + st['QH'] + st['QP'] - (st['Phpt'] - st['Pcomp'] + st['Ppt'])
        return st


def _ref_x_iso():
    """Unfired crank line at ISO traced down from the lever-0 idle region to N_MIN (continuation);
    gives the initial guess for the reference solution of any ambient."""
    T0, P0 = sim.ISO_T0, sim.ISO_P0
    n, p, pf = sim.combinator(10)
    xs, st = sim.solve_point(T0, P0, n * NPT_D, pf * sim.SHP_D, (0,) * 6)
    N, beta, t4r, phr, ppr = xs
    x = [N, n, beta, t4r, math.log(phr * DES['PRh']) / LN_PRH_D, math.log(ppr * DES['PRp']) / LN_PRP_D]
    S = Solver(1e-11)
    # fire-down: unfired at N, then march N down with the PT at rest
    steps = [N - k * (N - N_MIN) / 24.0 for k in range(25)]
    wf = st['WF']
    for i, nn in enumerate(steps):
        frac = max(0.0, 1.0 - i / 6.0)
        E = Env(T0=T0, P0=P0, WF=wf * frac, th=sim.vsv_angle(nn), b=sim.bleed_frac(nn), steady=True,
                gg_fix=nn, pt_fix=max(0.0, n * (1.0 - i / 6.0)))
        x[0], x[1] = nn, E.pt_fix
        S.Jinv = None
        x, r = S.solve(lambda z: gas_path(z, E), x, maxit=100)
    return x


REF_X_ISO = _ref_x_iso()


# =============================================================================
# 6. OPERATING PROGRAMME: the bridge / machinery control actions
# =============================================================================
DT_FAST, DT_SLOW = 0.1, 0.5


def choose_dt(eng):
    """Small step while things move fast (start sequence, lever moves, run-down, the first minute
    after any change), a larger step in settled running and at standstill.  Both divide one
    second, so the 1 Hz log falls on steps.  The shafts are implicit (backward Euler), the lags
    are integrated exactly, so the larger step is only a matter of accuracy, not stability."""
    if eng.phase in ('crank', 'purge', 'ignition', 'accel', 'rundown'):
        return DT_FAST
    if eng.phase == 'standstill':
        return DT_SLOW
    if eng.ops in ('lever_up', 'lever_down'):
        return DT_FAST
    if eng.t - eng.t_ops < 60.0 or (not eng.ready and eng.t - eng.ev.get('gg_idle', eng.t) < 60.0):
        return DT_FAST
    return DT_SLOW


def run_program(eng, program, logger=None):
    """program: list of actions executed in order
       ('wait', s)              keep doing what it does for s seconds
       ('start',)               machinery control start command (crank, purge, light, idle)
       ('wait_ready',)          until the warm-up at idle is complete
       ('lever', target, s)     the bridge moves the lever linearly to target over s seconds
       ('hold', s)              hold the lever for s seconds (cool-down if the lever is at 0)
       ('fuel_off',)            fuel shut-off (normal stop after cool-down)
       ('wait_stopped',)        until both shafts have stopped
    """
    def set_ops(o):
        if o != eng.ops:
            eng.ops = o
            eng.t_ops = eng.t

    def one_step(dt):
        eng.step(dt)
        if logger and abs(eng.t - round(eng.t)) < 1e-6:
            eng.t = float(round(eng.t))
            logger(eng)

    def advance_to(t_end):
        while eng.t < t_end - 1e-9:
            nxt = math.floor(eng.t + 1e-9) + 1.0        # land exactly on whole seconds
            one_step(min(choose_dt(eng), nxt - eng.t))
    nlev = 0
    for act in program:
        kind = act[0]
        if kind == 'wait':
            advance_to(eng.t + act[1])
        elif kind == 'start':
            eng.cmd_start()
            set_ops('start')
        elif kind == 'wait_ready':
            while not eng.ready:
                if eng.phase == 'run':
                    set_ops('warmup')
                advance_to(eng.t + 1.0)
                if eng.t - eng.ev['start_cmd'] > 3600:
                    raise RuntimeError('start did not complete')
            set_ops('idle')
        elif kind == 'lever':
            nlev += 1
            l0, l1, dur = eng.lever, float(act[1]), float(act[2])
            t0 = eng.t
            eng.ev['lever%d_start' % nlev] = t0
            set_ops('lever_up' if l1 >= l0 else 'lever_down')
            while eng.t < t0 + dur - 1e-9:
                nxt = math.floor(eng.t + 1e-9) + 1.0
                dt = min(choose_dt(eng), nxt - eng.t)
                # the lever moves continuously: its position at the end of the step is used
                eng.lever = l0 + (l1 - l0) * min(1.0, (eng.t + dt - t0) / dur)
                one_step(dt)
            eng.lever = l1
            eng.ev['lever%d_end' % nlev] = eng.t
        elif kind == 'hold':
            set_ops('hold' if eng.lever > 0.0 else 'cooldown')
            eng.ev['hold%d_start' % nlev] = eng.t
            advance_to(eng.t + act[1])
            eng.ev['hold%d_end' % nlev] = eng.t
        elif kind == 'fuel_off':
            eng.cmd_fuel_off()
            set_ops('rundown')
        elif kind == 'wait_stopped':
            while eng.ngg > 0.0 or eng.npt > 0.0:
                advance_to(eng.t + 1.0)
            eng.set_phase('standstill')
            eng.event('stopped')
            set_ops('shutdown')
            eng.brake = True
        else:
            raise KeyError(kind)


# =============================================================================
# 7. LOGGING: measured tags (same names, units, noise and rounding as the steady files)
# =============================================================================
MEAS = [t[0] for t in sim.TAGS] + ['LEVER_PCT']
NOISE = {t[0]: (t[3], t[4], t[5]) for t in sim.TAGS}
DNAMES = sim.DNAMES


def phase_label(eng):
    """One label per logged second for the truth files (never in the measured files)."""
    ph = eng.phase
    if ph == 'run':
        if eng.ops in ('lever_up', 'lever_down', 'hold', 'cooldown'):
            return {'lever_up': 'lever_ramp', 'lever_down': 'lever_down'}.get(eng.ops, eng.ops)
        return 'warmup' if not eng.ready else 'idle'
    if ph == 'standstill':
        return 'standstill' if 'start_cmd' not in eng.ev else 'stopped'
    return ph


def measured(eng):
    """Exact values of the logged tags: thermocouples lagged, everything else instantaneous."""
    st = eng.st
    return {
        'T_AMB_C': st['T0'] - 273.15, 'P_AMB_KPA': st['P0'], 'T2_C': st['T2'] - 273.15,
        'P2_KPA': st['P2'], 'NGG_RPM': eng.ngg * NGG_D, 'NPT_RPM': eng.npt * NPT_D,
        'WF_KGH': eng.WF * 3600.0, 'P3_KPA': st['P3'], 'T3_C': eng.TC['T3'] - 273.15,
        'P54_KPA': st['P54'], 'T54_C': eng.TC['T54'] - 273.15, 'T8_C': eng.TC['T8'] - 273.15,
        'SHP_KW': st['SHP'] / 1e3, 'LEVER_PCT': eng.lever}


INTERNAL = [
    ('t_s', lambda e, s: '%.0f' % e.t), ('phase', lambda e, s: phase_label(e)),
    ('fuel_loop', lambda e, s: e.loop if e.lit else 'off'),
    ('lever_pct', lambda e, s: '%.3f' % e.lever),
    ('npt_set_rpm', lambda e, s: '%.3f' % (sim.combinator(e.lever)[0] * NPT_D)),
    ('pitch_set', lambda e, s: '%.5f' % sim.combinator(e.lever)[1]),
    ('pitch', lambda e, s: '%.5f' % e.pitch), ('shaft_brake', lambda e, s: '%d' % e.brake),
    ('starter_on', lambda e, s: '%d' % e.st_on), ('starter_valve', lambda e, s: '%.4f' % e.st_u),
    ('starter_torque_Nm', lambda e, s: '%.2f' % s['Q_st']),
    ('T0_K', lambda e, s: '%.4f' % s['T0']), ('P0_kPa', lambda e, s: '%.4f' % s['P0']),
    ('Nc_gg_frac', lambda e, s: '%.6f' % (e.ngg / math.sqrt(s['T0'] / TREF))),
    ('NGG_rpm', lambda e, s: '%.3f' % (e.ngg * NGG_D)), ('NPT_rpm', lambda e, s: '%.3f' % (e.npt * NPT_D)),
    ('beta', lambda e, s: '%.5f' % s['beta']), ('surge_margin_pct', lambda e, s: '%.3f' % s['SM']),
    ('surge_margin_rise_pct', lambda e, s: '%.3f' % s['SMr']),
    ('PR_c', lambda e, s: '%.5f' % s['PR']), ('PR_surge_same_speed', lambda e, s: '%.5f' % s['PRsurge']),
    ('eta_c_is', lambda e, s: '%.5f' % s['eta_c']),
    ('vsv_deg_closed', lambda e, s: '%.4f' % e.th),
    ('vsv_schedule_deg', lambda e, s: '%.4f' % sim.vsv_angle(e.ngg / math.sqrt(s['T0'] / TREF))),
    ('bleed_frac_of_W2', lambda e, s: '%.6f' % e.b),
    ('bleed_schedule', lambda e, s: '%.6f' % sim.bleed_frac(e.ngg / math.sqrt(s['T0'] / TREF))),
    ('W2_kgs', lambda e, s: '%.5f' % s['W2']), ('W2c_kgs', lambda e, s: '%.5f' % s['W2c']),
    ('P2_kPa', lambda e, s: '%.4f' % s['P2']), ('P3_kPa', lambda e, s: '%.4f' % s['P3']),
    ('T3_true_K', lambda e, s: '%.3f' % s['T3']), ('W3_kgs', lambda e, s: '%.5f' % s['W3']),
    ('WF_kgh', lambda e, s: '%.4f' % (s['WF'] * 3600)), ('FAR_comb', lambda e, s: '%.6f' % s['far']),
    ('eta_comb', lambda e, s: '%.6f' % s['eta_b']),
    ('T4_TIT_K', lambda e, s: '%.3f' % s['T4']), ('T41_SOT_K', lambda e, s: '%.3f' % s['T41']),
    ('PR_hpt', lambda e, s: '%.5f' % s['PRh']), ('eta_hpt', lambda e, s: '%.5f' % s['eta_h']),
    ('nu_hpt_rel', lambda e, s: '%.5f' % s['nu_h']),
    ('T48_K', lambda e, s: '%.3f' % s['T48']), ('P48_kPa', lambda e, s: '%.4f' % s['P48']),
    ('T54_true_K', lambda e, s: '%.3f' % s['T54']), ('P54_kPa', lambda e, s: '%.4f' % s['P54']),
    ('PR_pt', lambda e, s: '%.5f' % s['PRp']), ('eta_pt', lambda e, s: '%.5f' % s['eta_p']),
    ('nu_pt_rel', lambda e, s: '%.5f' % s['nu_p']),
    ('T8_true_K', lambda e, s: '%.3f' % s['T5']), ('P5_kPa', lambda e, s: '%.4f' % s['P5']),
    ('W48_kgs', lambda e, s: '%.5f' % s['W48']),
    ('P_comp_kW', lambda e, s: '%.3f' % (s['Pcomp'] / 1e3)), ('P_hpt_kW', lambda e, s: '%.3f' % (s['Phpt'] / 1e3)),
    ('P_pt_kW', lambda e, s: '%.3f' % (s['Ppt'] / 1e3)), ('SHP_kW', lambda e, s: '%.3f' % (s['SHP'] / 1e3)),
    ('P_prop_kW', lambda e, s: '%.3f' % (s['Pprop'] / 1e3)),
    ('Q_net_gg_Nm', lambda e, s: '%.3f' % s['Q_net_gg']), ('Q_net_pt_Nm', lambda e, s: '%.3f' % s['Q_net_pt']),
    ('Tmetal_C_K', lambda e, s: '%.3f' % e.Tm['C']), ('Tmetal_H_K', lambda e, s: '%.3f' % e.Tm['H']),
    ('Tmetal_P_K', lambda e, s: '%.3f' % e.Tm['P']),
    ('Q_soak_C_kW', lambda e, s: '%.4f' % (s['QC'] / 1e3)), ('Q_soak_H_kW', lambda e, s: '%.4f' % (s['QH'] / 1e3)),
    ('Q_soak_P_kW', lambda e, s: '%.4f' % (s['QP'] / 1e3)),
    ('T3_TC_K', lambda e, s: '%.3f' % e.TC['T3']), ('T54_TC_K', lambda e, s: '%.3f' % e.TC['T54']),
    ('T8_TC_K', lambda e, s: '%.3f' % e.TC['T8']),
    ('max_residual', lambda e, s: '%.2e' % s['res']), ('energy_closure_rel', lambda e, s: '%.2e' % s['e_close']),
]


class Recorder:
    """Collects one row per logged second."""

    def __init__(self, t0_datetime, t_offset=0.0, extra=None):
        self.t0 = t0_datetime
        self.toff = t_offset
        self.rows = []
        self.extra = extra or {}

    def __call__(self, eng):
        ts = self.t0 + datetime.timedelta(seconds=int(round(eng.t - self.toff)))
        m = measured(eng)
        it = [f(eng, eng.st) for _, f in INTERNAL]
        it = ['' if v == 'nan' else v for v in it]      # undefined at standstill (no flow)
        self.rows.append((ts.strftime('%Y-%m-%d %H:%M:%S'), m, it, dict(self.extra), eng.t - self.toff,
                          phase_label(eng)))


def fmt_exact(m):
    return ['%.6f' % (m[k] + 0.0) for k in MEAS[:-1]] + ['%.2f' % (m['LEVER_PCT'] + 0.0)]


def fmt_noisy(m, rng):
    """Independent Gaussian noise per signal and sample (sigma as in sim.TAGS), then the historian
    rounding.  The lever is a command signal: logged without noise at 0.1 %."""
    out = []
    for k in MEAS[:-1]:
        sig, kind, nd = NOISE[k]
        v = m[k]
        s = sig if kind == 'abs' else sig * abs(v)
        v = v + rng.gauss(0.0, s)
        out.append(('%.' + str(nd) + 'f') % (round(v, nd) + 0.0))
    out.append('%.1f' % (round(m['LEVER_PCT'], 1) + 0.0))
    return out


def write_csv(path, header, rows):
    with open(path, 'w') as fh:
        fh.write(','.join(header) + '\n')
        for r in rows:
            fh.write(','.join(r) + '\n')


# =============================================================================
# 8. THE DATA PROGRAMME
# =============================================================================
ZERO = (0.0,) * 6
# start-up files: (number, kind, T_amb C, P_amb kPa, voyage lever %, ramp s, health, date/time of
# the first logged second, note).  Hot restarts: 'hot', with the preceding run described by
# HOT_PRE (lever, hold s) and the gap from fuel-off to the new start command.
STARTS = [
    (1, 'cold', 15.0, 101.30, 80.0, 120, ZERO, '2024-04-02 06:10:00', 'healthy ISO-like day'),
    (2, 'cold', -5.0, 102.40, 100.0, 150, ZERO, '2024-01-18 05:40:00', 'healthy cold day at full lever'),
    (3, 'cold', 35.0, 100.20, 60.0, 90, ZERO, '2024-07-25 13:20:00', 'healthy hot day'),
    (4, 'cold', 22.0, 100.80, 80.0, 120, (3.0, 1.2, 0, 0, 0, 0), '2024-05-06 07:00:00',
     'compressor fouling'),
    (5, 'cold', 8.0, 101.90, 90.0, 150, (0, 0, -2.0, 1.6, 0, 0), '2024-03-11 04:50:00', 'HPT erosion'),
    (6, 'cold', 28.0, 100.50, 70.0, 100, (0, 0, 0, 0, 2.0, 1.0), '2024-08-20 09:15:00', 'PT fouling'),
    (7, 'cold', 12.0, 99.60, 85.0, 140, (2.0, 0.8, -1.5, 1.2, 1.0, 0.8), '2024-10-14 06:30:00',
     'mixed degradation'),
    (8, 'hot', 18.0, 101.00, 75.0, 120, ZERO, '2024-06-03 10:45:00', 'healthy hot restart'),
    (9, 'hot', 30.0, 100.90, 80.0, 120, (4.0, 1.6, 0, 0, 0, 0), '2024-07-09 15:05:00',
     'hot restart with compressor fouling'),
]
HOT_PRE = {8: (80.0, 1200.0, 900.0), 9: (70.0, 900.0, 720.0)}   # lever, hold s, fuel-off -> start s
PRE_S = 60.0            # logged standstill before the start command
HOLD_S = 600.0          # steady hold at the voyage lever (>= 5 min asked; 10 min lets the heat soak settle)

# operations log: several voyages over four days, one engine (metal temperatures carry over)
OPS_T0 = datetime.datetime(2024, 5, 13, 0, 0, 0)
# day: (mean T C, diurnal amplitude K, P at 00:00 kPa, P drift kPa/day)
OPS_DAYS = [(14.0, 5.0, 101.60, -0.6), (19.0, 4.0, 101.00, -0.3), (24.0, 5.0, 100.70, 0.4),
            (9.0, 3.0, 101.10, 0.8)]
STOP = [('lever', 0.0, 90), ('hold', 300.0), ('fuel_off',), ('wait_stopped',)]
OPS_VOYAGES = [
    # (id, day, start hh:mm, health, actions after the warm-up, note)
    (1, 0, '07:30', ZERO, [('lever', 70.0, 120), ('hold', 1500.0), ('lever', 85.0, 60), ('hold', 1200.0)],
     'healthy'),
    (2, 0, '15:10', ZERO, [('lever', 90.0, 120), ('hold', 2400.0)], 'healthy'),
    (3, 1, '09:05', (1.0, 0.4, 0, 0, 0, 0), [('lever', 80.0, 120), ('hold', 1800.0), ('lever', 60.0, 60),
                                           ('hold', 900.0)], 'light compressor fouling'),
    (4, 2, '08:20', (2.0, 0.8, -0.5, 0.4, 0, 0), [('lever', 85.0, 150), ('hold', 2100.0)],
     'compressor fouling + onset of HPT erosion'),
    (5, 2, 'hot+900', (2.0, 0.8, -0.5, 0.4, 0, 0), [('lever', 65.0, 100), ('hold', 1200.0)],
     'hot restart 15 min after voyage 4'),
    (6, 3, '10:40', (3.0, 1.2, -1.0, 0.8, 0.5, 0.4), [('lever', 90.0, 150), ('hold', 2400.0),
                                                     ('lever', 75.0, 60), ('hold', 900.0)],
     'compressor fouling + HPT erosion + PT fouling'),
]
OPS_MARGIN = 600.0      # s logged before the start command and after both shafts have stopped


def const_amb(T0c, P0):
    return lambda t: (T0c + 273.15, P0)


def ops_amb(t):
    """Ship's ambient: a diurnal cycle per day plus a slow pressure drift (smooth in time)."""
    day = int(t // 86400.0)
    day = min(max(day, 0), len(OPS_DAYS) - 1)
    h = (t - 86400.0 * day) / 3600.0
    Tm, A, P00, dP = OPS_DAYS[day]
    T = Tm + A * math.sin(2.0 * math.pi * (h - 9.0) / 24.0) + 0.4 * math.sin(2.0 * math.pi * h / 2.7)
    P = P00 + dP * h / 24.0 + 0.05 * math.sin(2.0 * math.pi * h / 12.4)
    return T + 273.15, P


def run_start(spec):
    """One start-up file.  Returns the engine, the recorder and summary info."""
    num, kind, T0c, P0, lever, ramp, deg, t_first, note = spec
    eng = Engine(const_amb(T0c, P0), deg, 'start_%02d' % num)
    if kind == 'hot':
        lev_pre, hold_pre, gap = HOT_PRE[num]
        pre = [('start',), ('wait_ready',), ('lever', lev_pre, 120), ('hold', hold_pre)] + STOP
        run_program(eng, pre)
        t_off = eng.ev['fuel_off']
        pre_info = dict(lever=lev_pre, hold=hold_pre, gap=gap, t_stop=eng.t - t_off)
        run_program(eng, [('wait', max(0.0, t_off + gap - PRE_S - eng.t))])
    else:
        pre_info = None
    t_log0 = eng.t
    rec = Recorder(datetime.datetime.strptime(t_first, '%Y-%m-%d %H:%M:%S'), t_offset=t_log0)
    rec(eng)   # the first logged second (standstill) before anything happens
    e0 = dict(eng.energy)
    m0 = dict(eng.mom)
    w0 = (eng.ngg * WG_D, eng.npt * WP_D)
    ke0 = 0.5 * J_GG * (eng.ngg * WG_D) ** 2 + 0.5 * J_PT * (eng.npt * WP_D) ** 2
    em0 = sum(MC[z] * eng.Tm[z] for z in ZONES)
    metal0 = dict(eng.Tm)
    prog = [('wait', PRE_S), ('start',), ('wait_ready',), ('lever', lever, ramp), ('hold', HOLD_S)]
    run_program(eng, prog, rec)
    e1 = dict(eng.energy)
    ke1 = 0.5 * J_GG * (eng.ngg * WG_D) ** 2 + 0.5 * J_PT * (eng.npt * WP_D) ** 2
    em1 = sum(MC[z] * eng.Tm[z] for z in ZONES)
    d = {k: e1[k] - e0[k] for k in e0}
    resid = d['fuel'] + d['starter'] - d['prop'] - d['losses'] - d['exh'] - d['metal'] - (ke1 - ke0) \
        - (em1 - em0)
    info = dict(pre=pre_info, t_log0=t_log0, energy=d, dKE=ke1 - ke0, dEm=em1 - em0, e_resid=resid,
                metal0=metal0, mom=(eng.mom['gg'] - m0['gg'], J_GG * (eng.ngg * WG_D - w0[0]),
                                    eng.mom['pt'] - m0['pt'], J_PT * (eng.npt * WP_D - w0[1])))
    return eng, rec, info


def run_operations():
    eng = Engine(ops_amb, ZERO, 'ops')
    rec = Recorder(OPS_T0, 0.0)
    voy_info = []
    for iv, (vid, day, hhmm, deg, acts, note) in enumerate(OPS_VOYAGES):
        hot = hhmm.startswith('hot+')
        if hot:
            t_cmd = float(round(voy_info[-1]['t_fuel_off'] + float(hhmm[4:])))
        else:
            hh, mm = hhmm.split(':')
            t_cmd = day * 86400.0 + int(hh) * 3600.0 + int(mm) * 60.0
            t_log = t_cmd - OPS_MARGIN
            if eng.t < t_log - 3600.0:
                eng.skip(t_log - eng.t)
            elif eng.t < t_log:
                run_program(eng, [('wait', t_log - eng.t)])
        rec.extra = dict(voyage=vid, deg=deg)
        if not hot:
            rec(eng)          # first logged second (standstill), before any step
        eng.deg = tuple(float(v) for v in deg)
        eng.refs = {}
        run_program(eng, [('wait', t_cmd - eng.t), ('start',), ('wait_ready',)] + acts + STOP, rec)
        ev = dict(eng.ev)
        info = dict(id=vid, deg=deg, note=note, t_cmd=ev['start_cmd'], t_fuel_off=ev['fuel_off'],
                    t_stopped=ev['stopped'], ev=ev, hot=eng.hot, amb_start=ops_amb(ev['start_cmd']),
                    acts=acts, min_sm=eng.min_sm, max_beta=eng.max_beta,
                    max_T54_start=eng.max_T54_start)
        eng.min_sm, eng.max_beta, eng.max_T54_start = 1e9, -1e9, 0.0
        voy_info.append(info)
        nxt_hot = iv + 1 < len(OPS_VOYAGES) and OPS_VOYAGES[iv + 1][2].startswith('hot+')
        if not nxt_hot:
            run_program(eng, [('wait', OPS_MARGIN)], rec)
    return eng, rec, voy_info


# =============================================================================
# 9. CHECKS
# =============================================================================
CMP_TAGS = ['P2_KPA', 'NGG_RPM', 'NPT_RPM', 'WF_KGH', 'P3_KPA', 'T3_C', 'P54_KPA', 'T54_C', 'T8_C', 'SHP_KW']


def sim_measured(st):
    return {'P2_KPA': st['P2'], 'NGG_RPM': st['NGG'], 'NPT_RPM': st['NPT'], 'WF_KGH': st['WF'] * 3600.0,
            'P3_KPA': st['P3'], 'T3_C': st['T3'] - 273.15, 'P54_KPA': st['P54'], 'T54_C': st['T54'] - 273.15,
            'T8_C': st['T5'] - 273.15, 'SHP_KW': st['SHP'] / 1e3}


def rel_or_abs(tag, a, b):
    """Temperatures compared in K, everything else relative."""
    if tag.endswith('_C'):
        return a - b
    return (a - b) / b if b != 0 else a - b


def noise_sigma(tag, v):
    sig, kind, nd = NOISE[tag]
    return sig if kind == 'abs' else sig * abs(v)


def x_from_sim(xs, st):
    N, beta, t4r, phr, ppr = xs
    return [st['NGG'] / NGG_D, st['NPT'] / NPT_D, beta, t4r, math.log(phr * DES['PRh']) / LN_PRH_D,
            math.log(ppr * DES['PRp']) / LN_PRP_D]


def dyn_steady(T0, P0, lever, deg, xs=None, st=None):
    """The dynamic model's own equilibrium (shaft accelerations zero, actuators on schedule, metal
    soaked, PT on the combinator speed, SHP = propeller power), solved by Newton."""
    n, p, pf = sim.combinator(lever)
    if xs is None:
        xs, st = sim.solve_point(T0, P0, n * NPT_D, pf * sim.SHP_D, deg)
    x = x_from_sim(xs, st)
    x[3] *= 1.001
    x[0] *= 0.999
    E = Env(T0=T0, P0=P0, deg=deg, pitch=p, WF=st['WF'] * 1.002)
    x, sd = solve_steady_pt(E, n, x, tol=1e-12, sched=True)
    return sd


def check_model(L):
    P = L.append
    P('1. The dynamic gas path against sim.py at steady state')
    P('   (a) dyn.gas_path evaluated at sim.py\'s converged points (actuators on schedule, no heat flux,')
    P('       no acceleration): all six residuals must vanish (sim.py solves to 1e-10)')
    worst = 0.0
    pts = [(15.0, 101.325, 100.0, ZERO), (-5.0, 102.0, 60.0, (2.0, 0.8, 0, 0, 0, 0)),
           (35.0, 99.5, 48.5, (0, 0, -2.0, 1.6, 1.0, 1.0)), (15.0, 101.325, 30.0, ZERO),
           (25.0, 100.0, 86.0, (2.43, -0.74, 2.98, -2.84, 0.33, 0.32))]
    for T0c, P0, lev, deg in pts:
        n, p, pf = sim.combinator(lev)
        xs, st = sim.solve_point(T0c + 273.15, P0, n * NPT_D, pf * sim.SHP_D, deg)
        E = Env(T0=T0c + 273.15, P0=P0, th=sim.vsv_angle(xs[0]), b=sim.bleed_frac(xs[0]), deg=deg,
                pitch=p, steady=True, WF=st['WF'])
        r, sd = gas_path(x_from_sim(xs, st), E, full=True)
        m = max(abs(v) for v in r)
        worst = max(worst, m)
        P('   T0 %5.1f C  P0 %6.2f  lever %5.1f  D=%s  max|r| %.1e  SHP %9.3f / %9.3f kW  e_close %.0e'
          % (T0c, P0, lev, ','.join('%g' % v for v in deg), m, sd['SHP'] / 1e3, st['SHP'] / 1e3, sd['e_close']))
    P('   max residual %.1e  %s' % (worst, 'PASS' if worst < 1e-9 else 'FAIL'))
    P('')
    P('2. Compressor map extension below the lowest speed line N_L = %.2f (VSV 35 deg, bleed 6 %%)' % N_LOW)
    P('   %6s | %s' % ('Nc', 'W2c kg/s / PR / eta_is   at beta = 0, 0.5, 1  | PR_surge'))
    for N in (0.05, 0.10, 0.20, 0.30, 0.40, N_LOW * (1 - 1e-12), N_LOW, 0.50, 0.60):
        cells = []
        for bt in (0.0, 0.5, 1.0):
            W, PR, eta, PRs = comp_map_dyn(N, bt, sim.VSV_MAX, sim.BLEED_MAX)
            cells.append('%6.2f/%6.3f/%.3f' % (W, PR, eta))
        P('   %6.3f | %s | %.3f' % (N, '  '.join(cells), PRs))
    dmax = 0.0
    for bt in (0.0, 0.25, 0.5, 0.75, 1.0):
        a = comp_map_dyn(N_LOW * (1 - 1e-12), bt, 35.0, 0.06)
        b = comp_map_dyn(N_LOW, bt, 35.0, 0.06)
        dmax = max(dmax, max(abs(u / v - 1) for u, v in zip(a, b)))
    P('   continuity at N_L: max relative jump %.1e  %s' % (dmax, 'PASS' if dmax < 1e-9 else 'FAIL'))
    P('   same speed line at and above N_L as sim.comp_map: %s' % (
        'PASS' if all(abs(comp_map_dyn(N, bt, sim.vsv_angle(N), sim.bleed_frac(N))[1]
                          - (1 + DES['sPR'] * sim.comp_map(N, bt)[1])) < 1e-12
                      for N in (0.45, 0.6, 0.8, 1.0) for bt in (0.0, 0.5, 1.0)) else 'FAIL'))
    P('')
    P('3. Turbine efficiency vs blade-speed ratio, stall-torque extension below nu = %.2f' % NU_STALL_P)
    P('   %5s %9s %9s   (eta / eta_design)' % ('nu', 'HPT', 'PT'))
    for nu in (0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.5, 2.0, 2.5):
        P('   %5.2f %9.4f %9.4f' % (nu, eta_rel_ext(nu, sim.HPT_KNU, sim.HPT_NUOPT, NU_STALL_H, STALL_H),
                                  eta_rel_ext(nu, sim.PT_KNU, sim.PT_NUOPT, NU_STALL_P, STALL_P)))
    for name, k, no, nl, AB in (('HPT', sim.HPT_KNU, sim.HPT_NUOPT, NU_STALL_H, STALL_H),
                                ('PT', sim.PT_KNU, sim.PT_NUOPT, NU_STALL_P, STALL_P)):
        h = 1e-6
        v1, v2 = eta_rel_ext(nl - 1e-12, k, no, nl, AB), eta_rel_ext(nl, k, no, nl, AB)
        s1 = (eta_rel_ext(nl - 1e-12, k, no, nl, AB) - eta_rel_ext(nl - h, k, no, nl, AB)) / (h - 1e-12)
        s2 = (eta_rel_ext(nl + h, k, no, nl, AB) - eta_rel_ext(nl, k, no, nl, AB)) / h
        P('   %-3s C1 at nu_L: value jump %.1e, slope %.4f / %.4f; torque at standstill / torque at '
          'nu = 1 (same expansion) = %.2f' % (name, v2 - v1, s1, s2, AB[0] / sim.turb_eta_rel(1.0, k, no)))
    P('')


def check_start(L, num, eng, rec, info, spec):
    """Timings, surge, closures, energy and momentum, steady end against sim.py."""
    P = L.append
    ev = {k: v - info['t_log0'] for k, v in eng.ev.items()}
    rows = rec.rows
    T0c, P0, lever, deg = spec[2], spec[3], spec[4], spec[6]
    it_idx = {name: i for i, (name, _) in enumerate(INTERNAL)}

    def col(name):
        return [float(r[2][it_idx[name]]) if r[2][it_idx[name]] else float('nan') for r in rows]
    res = {}
    ngg_purge = [r[1]['NGG_RPM'] for r in rows if ev['purge'] + 5 <= r[4] <= ev['ignition']]
    res['purge_rpm'] = (min(ngg_purge), max(ngg_purge))
    res['purge_s'] = ev['ignition'] - ev['purge']
    res['crank_s'] = ev['purge'] - ev['start_cmd']
    res['light_s'] = ev['lightoff'] - ev['ignition']
    res['accel_s'] = ev['gg_idle'] - ev['lightoff']
    res['ptup_s'] = ev['pt_at_set'] - ev['brake_release']
    res['warm_s'] = ev['ready'] - ev['gg_idle']
    res['ramp_s'] = ev['lever1_end'] - ev['lever1_start']
    res['hold_s'] = ev['hold1_end'] - ev['hold1_start']
    beta = col('beta')
    sm_run = [float(r[2][it_idx['surge_margin_pct']]) for r in rows if r[1]['NGG_RPM'] > 0.40 * NGG_D]
    res['max_beta'] = eng.max_beta
    res['min_smr'] = eng.min_sm
    res['min_sm_run'] = min(sm_run)
    res['T54_start'] = eng.max_T54_start - 273.15
    ok_t = (0.20 * NGG_D <= res['purge_rpm'][0] and res['purge_rpm'][1] <= 0.25 * NGG_D
            and 30 <= res['purge_s'] <= 60 and res['light_s'] < 10 and res['accel_s'] < 120
            and res['warm_s'] >= 180 and 60 <= res['ramp_s'] <= 180 and res['hold_s'] >= 300)
    ok_s = res['max_beta'] < 0.95 and res['min_smr'] > 2.0 and max(beta) < 1.0
    P('   start_%02d  %-4s %5.1f C %6.2f kPa lever %5.1f  D=%s  (%s)' % (
        num, spec[1], T0c, P0, lever, ','.join('%g' % v for v in deg), spec[8]))
    if info['pre']:
        pi = info['pre']
        P('      previous run: lever %.0f for %.0f s, normal stop, fuel off -> start command %.0f s; '
          'metal at the start command C/H/P = %.0f/%.0f/%.0f C' % (
              pi['lever'], pi['hold'], pi['gap'], info['metal0']['C'] - 273.15,
              info['metal0']['H'] - 273.15, info['metal0']['P'] - 273.15))
    P('      crank %.1f s, purge %.1f s at %.0f..%.0f rpm, ignition->light-off %.1f s, light-off->GG idle '
      '%.1f s, brake release->NPT at set %.1f s, warm-up %.0f s, lever ramp %.0f s, hold %.0f s   %s'
      % (res['crank_s'], res['purge_s'], res['purge_rpm'][0], res['purge_rpm'][1], res['light_s'],
         res['accel_s'], res['ptup_s'], res['warm_s'], res['ramp_s'], res['hold_s'], 'PASS' if ok_t else 'FAIL'))
    P('      surge: max beta %.3f, min pressure-rise margin (PRs-PR)/(PR-1) %.1f %%, min SM (PRs/PR-1) '
      'above 40 %% NGG %.1f %%; peak T54 harness during start %.0f C   %s'
      % (res['max_beta'], res['min_smr'], res['min_sm_run'], res['T54_start'], 'PASS' if ok_s else 'FAIL'))
    en = info['energy']
    rel = info['e_resid'] / en['fuel']
    P('      closures: max Newton residual %.1e, max gas-path energy closure %.1e; run energy balance '
      '(fuel %.3f GJ + starter %.1f MJ = propeller %.3f GJ + losses %.1f MJ + exhaust/bleed %.3f GJ'
      % (eng.max_res, eng.max_eclose, en['fuel'] / 1e9, en['starter'] / 1e6, en['prop'] / 1e9,
         en['losses'] / 1e6, en['exh'] / 1e9))
    P('                + dKE %.1f MJ + metal %.1f MJ + enclosure %.2f MJ): residual %.1e of fuel   %s'
      % (info['dKE'] / 1e6, info['dEm'] / 1e6, en['metal'] / 1e6, rel, 'PASS' if abs(rel) < 1e-4 else 'FAIL'))
    # momentum from the logged 1 Hz torques (independent of the integrator: trapezoid vs J dw)
    ts = [r[4] for r in rows]
    qg = col('Q_net_gg_Nm')
    ng = col('NGG_rpm')

    def mom(q, n, J, t_a, t_b):
        ia = min(range(len(ts)), key=lambda i: abs(ts[i] - t_a))
        ib = min(range(len(ts)), key=lambda i: abs(ts[i] - t_b))
        integ = sum(0.5 * (q[i] + q[i + 1]) * (ts[i + 1] - ts[i]) for i in range(ia, ib))
        dl = J * (n[ib] - n[ia]) * math.pi / 30.0
        return integ, dl
    a1, b1 = mom(qg, ng, J_GG, ev['start_cmd'], ev['gg_idle'] + 10)
    mg, jg, mp, jp = info['mom']
    ok_m = abs(a1 - b1) < 0.05 * abs(b1) and abs(mg - jg) < 1e-6 * J_GG * WG_D \
        and abs(mp - jp) < 1e-6 * J_PT * WP_D
    P('      angular momentum: step sums of the logged net torques vs J dw over the file: GG %.3f / %.3f,'
      ' PT %.3f / %.3f N m s;' % (mg, jg, mp, jp))
    P('      1 Hz trapezoid of the logged GG net torque from the start command to idle: %.0f vs J dw %.0f '
      'N m s (%.1f %%)   %s' % (a1, b1, (a1 / b1 - 1) * 100, 'PASS' if ok_m else 'FAIL'))
    # steady end
    n, p, pf = sim.combinator(lever)
    T0 = T0c + 273.15
    xs, sst = sim.solve_point(T0, P0, n * NPT_D, pf * sim.SHP_D, tuple(float(v) for v in deg))
    ref = sim_measured(sst)
    sd = dyn_steady(T0, P0, lever, tuple(float(v) for v in deg), xs, sst)
    ident = max(abs(rel_or_abs(k, v, ref[k])) for k, v in sim_measured(sd).items())
    last = rows[-1][1]
    diffs = {k: rel_or_abs(k, last[k], ref[k]) for k in CMP_TAGS}
    frac = max(abs(last[k] - ref[k]) / noise_sigma(k, ref[k]) for k in CMP_TAGS)
    P('      steady end (last logged second) vs sim.solve_point: ' + ', '.join(
        '%s %+.1e%s' % (k.split('_')[0], v, 'K' if k.endswith('_C') else '') for k, v in diffs.items()))
    P('      largest end difference = %.4f of the channel noise sigma (limiter %s); the dynamic model\'s own '
      'equilibrium equals sim.py to %.1e   %s' % (frac, sst['limiter'], ident,
                                                  'PASS' if frac < 0.05 and ident < 1e-7 else 'FAIL'))
    res.update(end_frac=frac, ident=ident, ok=ok_t and ok_s and ok_m and abs(rel) < 1e-4
               and frac < 0.05 and ident < 1e-7, sim=sst)
    return res


def idle_point(T0, P0, deg=ZERO):
    """Steady ground idle (lever 0: PT governed at 2160 rpm, zero pitch), reached by marching the
    lever down from 10 % (sim.py's domain stops above it)."""
    n, p, pf = sim.combinator(10.0)
    xs, st = sim.solve_point(T0, P0, n * NPT_D, pf * sim.SHP_D, deg)
    x = x_from_sim(xs, st)
    E = Env(T0=T0, P0=P0, deg=deg, WF=st['WF'])
    for lev in (10.0, 7.5, 5.0, 2.5, 0.0):
        n, p, pf = sim.combinator(lev)
        E.pitch = p
        x, sd = solve_steady_pt(E, n, x, tol=1e-11, sched=True)
    return sd


def crank_torque(T0, P0, ngg):
    """Steady unfired drag torque of the GG at a given speed (PT held), N m."""
    E = Env(T0=T0, P0=P0, WF=0.0, steady=True, gg_fix=ngg, pt_fix=0.0)
    nc = ngg / math.sqrt(T0 / TREF)
    E.th, E.b = sim.vsv_angle(nc), sim.bleed_frac(nc)
    g = REF_X_ISO
    x = [ngg, 0.0, g[2], g[3] * T0 / TREF, g[4] * (nc / N_MIN) ** 2, g[5] * (nc / N_MIN) ** 2]
    S = Solver(1e-11)
    for _ in range(40):                      # T4 guess must not be below T3
        if _ev(lambda z: gas_path(z, E), x) is not None:
            break
        x[3] *= 1.05
    x, r = S.solve(lambda z: gas_path(z, E), x, maxit=200)
    return -gas_path(x, E, full=True)[1]['Q_net_gg'] - QF_GG0 * smooth_lowspeed(ngg, NF_GG)


# =============================================================================
# 10. OUTPUT: files, dynamics datasheet, checks
# =============================================================================
def write_dynamics(voy, idle):
    """Vendor-style note of the dynamic data (what a maker states; no map equations)."""
    L = []
    P = L.append
    ev = voy[0]['ev']
    P('MGT-25 MARINE GAS TURBINE -- DYNAMIC DATA, START AND STOP SEQUENCE (supplement to design.txt)')
    P('')
    P('ROTOR INERTIAS (polar moments of inertia)')
    P('  Gas generator rotor (compressor + HP turbine + accessory drive, referred)   %6.1f kg m2' % J_GG)
    P('  Power turbine rotor                                                         %6.1f kg m2' % J_PTR)
    P('  Reduction gear + shafting + CPP incl. entrained water, referred to PT speed %6.1f kg m2' % J_DRV)
    P('  Total on the PT shaft (referred to PT speed)                                %6.1f kg m2' % J_PT)
    P('  The torque meter sits between the PT rotor and the reduction gear.')
    P('')
    P('STARTER')
    P('  Air-turbine starter on the accessory gearbox; torque at the GG shaft falls linearly with speed')
    P('  Stall torque (full air)                 %6.0f N m' % ST_Q0)
    P('  Runaway speed                           %6.0f rpm NGG (%.0f %%)' % (ST_NRUN * NGG_D, ST_NRUN * 100))
    P('  Starter air valve opening ramp          %6.0f s' % ST_RAMP)
    P('  Cut-out (air valve closed, clutch over-runs) %4.0f rpm NGG (%.0f %%)' % (ST_CUTOUT * NGG_D, ST_CUTOUT * 100))
    P('  GG drag at purge speed, unfired, ISO    %6.0f N m (%.0f kW)' % (
        crank_torque(sim.ISO_T0, sim.ISO_P0, PURGE_N), crank_torque(sim.ISO_T0, sim.ISO_P0, PURGE_N)
        * PURGE_N * WG_D / 1e3))
    P('  Bearing breakaway torque at standstill  GG %.0f N m, PT shaft line %.0f N m (referred)' % (QF_GG0, QF_PT0))
    P('  Shaft brake: %.0f kN m, applied at standstill, released when the GG reaches ground idle' % (Q_BRAKE / 1e3))
    P('')
    P('START SEQUENCE (machinery control system)')
    P('  1  Start command: shaft brake on, starter air valve opens along its ramp, crank')
    P('  2  Purge at %.0f rpm NGG (%.0f %%), starter air modulated to hold the speed, %.0f s'
      % (PURGE_N * NGG_D, PURGE_N * 100, PURGE_S))
    P('  3  Ignition on, fuel valve opens to the light-off flow %.0f kg/h' % (WF_LIGHT * 3600))
    P('  4  Light-off declared when the T54 harness rises %.0f K (typically %.1f s after ignition)'
      % (LIGHT_DT, ev['lightoff'] - ev['ignition']))
    P('  5  Acceleration on a scheduled NGG rate of %.2f %%/s (reduced just after light-off), within the'
      % (NDOT_START * 100))
    P('     acceleration limit (fuel/P3 schedule below) and the T54 limit; starter cut-out at %.0f rpm'
      % (ST_CUTOUT * NGG_D))
    P('  6  Ground-idle cap %.0f rpm NGG (%.0f %%) reached typically %.0f s after light-off; shaft brake'
      % (NGG_GI * NGG_D, NGG_GI * 100, ev['gg_idle'] - ev['lightoff']))
    P('     released; the PT runs up to the combinator minimum speed %.0f rpm (typically %.0f s) and the'
      % (0.6 * NPT_D, ev['pt_at_set'] - ev['brake_release']))
    P('     PT speed governor takes over; NGG settles at the idle speed that just carries the zero-pitch')
    P('     propeller (see idle table)')
    P('  7  Warm-up at idle: %.0f s after a cold start, %.0f s after a hot restart; then the bridge may'
      % (WARMUP_COLD, WARMUP_HOT))
    P('     move the lever (recommended ramp 1-3 min from 0 to voyage setting)')
    P('')
    P('GROUND IDLE (lever 0: NPT %.0f rpm, pitch 0), new & clean' % (0.6 * NPT_D))
    P('  %6s %8s %8s %8s %8s %8s %8s %8s' % ('T_amb C', 'NGG rpm', 'NPT rpm', 'WF kg/h', 'P3 kPa', 'T3 C',
                                             'T54 C', 'T8 C'))
    for T0c, sd in idle:
        P('  %6.0f %8.0f %8.0f %8.0f %8.1f %8.0f %8.0f %8.0f' % (
            T0c, sd['NGG'], sd['NPT'], sd['WF'] * 3600, sd['P3'], sd['T3'] - 273.15, sd['T54'] - 273.15,
            sd['T5'] - 273.15))
    P('  (sea level, 101.325 kPa; shaft power at the torque meter %.0f kW)' % (idle[1][1]['SHP'] / 1e3))
    P('')
    P('NORMAL STOP')
    P('  Lever to 0 (the combinator brings PT speed and pitch down), cool-down at idle >= 5 min, fuel')
    P('  shut-off.  Run-down from idle: GG at rest after about %.0f s, PT (zero pitch, in water) after'
      % (ev.get('gg_stop', ev['stopped']) - ev['fuel_off']))
    P('  about %.0f s; the shaft brake is applied when the PT has stopped.' % (
        max(v for k, v in ev.items() if k == 'pt_stop' or k == 'stopped') - ev['fuel_off']))
    P('  Hot restart permitted immediately after the run-down; purge as for a cold start.')
    P('')
    P('FUEL CONTROL')
    P('  PT speed governor on the combinator speed (PI, gain scheduled on propeller load, with a lever')
    P('  feed-forward of the combinator power demand), minimum-select')
    P('  with: GG speed governor (ground-idle cap during start and warm-up, %.0f rpm otherwise),'
      % sim.NGG_MAX)
    P('  T54 limiter %.0f C acting on the T54 harness, acceleration limit; maximum-select with the' % (T54_LIM - 273.15))
    P('  deceleration limit and the minimum flow %.0f kg/h.  At the T54 or NGG limit the load control'
      % (WF_MIN_LIT * 3600))
    P('  reduces pitch (PT speed stays on the combinator).')
    P('  Acceleration limit, fuel/P3 in kg/h per kPa, on corrected NGG:')
    P('    ' + '  '.join('%5.0f %%: %.2f' % (n * 100, r) for n, r in zip(RU_ACC_N, RU_ACC)))
    P('  Deceleration limit %.2f kg/h per kPa' % RU_DEC)
    P('')
    P('ACTUATORS AND SENSORS (first-order time constants)')
    P('  VSV actuator %.1f s, handling-bleed valve %.1f s, fuel metering %.2f s' % (TAU_VSV, TAU_BLEED, TAU_WF))
    P('  CPP pitch: %.1f s lag, rate limit %.0f %% of design pitch per s' % (TAU_PITCH, PITCH_RATE * 100))
    P('  Thermocouples: T3 %.0f s, T54 harness %.0f s, T8 %.0f s at idle flow and above; slower at lower'
      % (TAU_TC['T3'], TAU_TC['T54'], TAU_TC['T8']))
    P('  flow (~flow^-0.5), %.0f s in still air (standstill); pressures, speeds, fuel flow and torque' % TAU_TC_STILL)
    P('  meter are fast (no lag at 1 Hz logging)')
    P('')
    P('HEAT SOAK (lumped casing zones; time constant at rated flow / at standstill)')
    for z, name in (('C', 'compressor rear / diffuser / combustor casing (affects T3)'),
                    ('H', 'HPT stage 2 / inter-turbine duct (affects T54)'),
                    ('P', 'PT casing / exhaust collector (affects T8)')):
        P('  %s: %-58s %4.0f kJ/K, %5.0f s / %4.0f min' % (z, name, MC[z] / 1e3, MC[z] / HA_D[z],
                                                          MC[z] / HA_NC[z] / 60.0))
    with open(os.path.join(HERE, 'dynamics.txt'), 'w') as fh:
        fh.write('\n'.join(L) + '\n')


def main():
    os.makedirs(OUTDIR, exist_ok=True)
    L = ['indep3 start-up / operations self-checks (generated by dyn.py)', '=' * 78]
    check_model(L)
    L.append('4. Start-ups: timings, surge, closures, energy, momentum, steady end vs sim.py')
    L.append('   (times in s; the steady end is the last logged second, compared with sim.solve_point at')
    L.append('    the same lever, ambient and health; temperatures in K, the rest relative)')
    head = ['TIMESTAMP'] + MEAS
    ihead = ['TIMESTAMP'] + [n for n, _ in INTERNAL] + ['true_' + d for d in DNAMES]
    srows = []
    allok = True
    for spec in STARTS:
        num = spec[0]
        eng, rec, info = run_start(spec)
        rng = random.Random(7300 + num)
        dd = ['%.2f' % float(v) for v in spec[6]]
        write_csv(os.path.join(OUTDIR, 'start_%02d.csv' % num), head,
                  [[r[0]] + fmt_noisy(r[1], rng) for r in rec.rows])
        write_csv(os.path.join(OUTDIR, 'start_%02d_exact.csv' % num), head,
                  [[r[0]] + fmt_exact(r[1]) for r in rec.rows])
        write_csv(os.path.join(OUTDIR, 'start_%02d_internal.csv' % num), ihead,
                  [[r[0]] + r[2] + dd for r in rec.rows])
        res = check_start(L, num, eng, rec, info, spec)
        allok = allok and res['ok']
        ev = {k: v - info['t_log0'] for k, v in eng.ev.items()}
        pre = ''
        if info['pre']:
            pre = 'lever %.0f %% for %.0f s then normal stop; fuel off %.0f s before the start command' % (
                info['pre']['lever'], info['pre']['hold'], info['pre']['gap'])
        srows.append(['start_%02d' % num, spec[1], rec.rows[0][0], '%.1f' % spec[2], '%.2f' % spec[3],
                      '%.1f' % spec[4], '%d' % spec[5]] + dd + [
            '%.1f' % ev[k] for k in ('start_cmd', 'purge', 'ignition', 'lightoff', 'starter_cutout',
                                     'gg_idle', 'pt_at_set', 'ready', 'lever1_start', 'lever1_end',
                                     'hold1_end')] + [
            '%.0f' % rec.rows[-1][1]['NGG_RPM'], pre, spec[8]])
        print('start_%02d done  (%.1f s)' % (num, time.time() - T_START))
    write_csv(os.path.join(OUTDIR, 'startups.csv'),
              ['file', 'kind', 'first_timestamp', 'T_AMB_C', 'P_AMB_KPA', 'voyage_lever_pct', 'lever_ramp_s']
              + ['true_' + d for d in DNAMES]
              + ['t_start_cmd_s', 't_purge_s', 't_ignition_s', 't_lightoff_s', 't_starter_cutout_s',
                 't_gg_idle_s', 't_npt_idle_s', 't_warmup_end_s', 't_lever_start_s', 't_lever_end_s',
                 't_end_s', 'NGG_end_rpm', 'previous_run', 'note'], srows)
    L.append('')
    # ------------------------------------------------------------------ operations log
    eng, rec, voy = run_operations()
    rng = random.Random(20240513)
    write_csv(os.path.join(OUTDIR, 'operations_log.csv'), head, [[r[0]] + fmt_noisy(r[1], rng) for r in rec.rows])
    it_idx = {name: i for i, (name, _) in enumerate(INTERNAL)}
    keep = ['phase', 'fuel_loop', 'pitch', 'beta', 'surge_margin_pct', 'vsv_deg_closed', 'bleed_frac_of_W2',
            'T4_TIT_K', 'T41_SOT_K', 'T54_true_K', 'Tmetal_H_K']
    write_csv(os.path.join(OUTDIR, 'operations_truth.csv'),
              head + ['voyage'] + keep + ['true_' + d for d in DNAMES],
              [[r[0]] + fmt_exact(r[1]) + ['%d' % r[3]['voyage']] + [r[2][it_idx[k]] for k in keep]
               + ['%.2f' % float(v) for v in r[3]['deg']] for r in rec.rows])
    vrows = []
    L.append('5. Operations log (operations_log.csv / operations_truth.csv)')
    L.append('   %d rows at 1 Hz, %d voyages; logged from %.0f s before each start command to %.0f s after'
             % (len(rec.rows), len(voy), OPS_MARGIN, OPS_MARGIN))
    L.append('   both shafts have stopped (a hot restart follows its previous stop without a gap)')
    ts_of = {}
    for r in rec.rows:
        ts_of[int(round(r[4]))] = r
    for v in voy:
        ev = v['ev']
        stamp = lambda t: (OPS_T0 + datetime.timedelta(seconds=int(round(t)))).strftime('%Y-%m-%d %H:%M:%S')
        prog = ' '.join('%s%.0f/%.0fs' % ('L' if a[0] == 'lever' else 'H', a[1], a[2] if a[0] == 'lever' else a[1])
                        if a[0] == 'lever' else 'hold%.0fs' % a[1] for a in v['acts'])
        vrows.append(['%d' % v['id'], 'hot' if v['hot'] else 'cold', stamp(v['t_cmd']), stamp(ev['ready']),
                      stamp(v['t_fuel_off']), stamp(v['t_stopped']), '%.1f' % (v['amb_start'][0] - 273.15),
                      '%.2f' % v['amb_start'][1], prog] + ['%.2f' % float(d) for d in v['deg']]
                     + ['%.3f' % v['max_beta'], '%.1f' % v['min_sm'], v['note']])
        L.append('   voyage %d %-4s start %s  light-off +%.1f s  GG idle +%.1f s  fuel off %s  stopped +%.0f s  '
                 'max beta %.3f  min rise margin %.1f %%  peak start T54 %.0f C' % (
                     v['id'], 'hot' if v['hot'] else 'cold', stamp(v['t_cmd']), ev['lightoff'] - ev['start_cmd'],
                     ev['gg_idle'] - ev['start_cmd'], stamp(v['t_fuel_off']), v['t_stopped'] - v['t_fuel_off'],
                     v['max_beta'], v['min_sm'], v['max_T54_start'] - 273.15))
        # end of each hold at a lever > 0 against sim.py at the ambient of that second
        k = 1
        while 'hold%d_end' % k in ev:
            te = int(round(ev['hold%d_end' % k]))
            lev = ts_of[te][1]['LEVER_PCT'] if te in ts_of else 0.0
            if lev > 0 and te in ts_of:
                m = ts_of[te][1]
                T0, P0 = m['T_AMB_C'] + 273.15, m['P_AMB_KPA']
                n, p, pf = sim.combinator(lev)
                xs, sst = sim.solve_point(T0, P0, n * NPT_D, pf * sim.SHP_D, tuple(float(d) for d in v['deg']))
                ref = sim_measured(sst)
                frac = max(abs(m[t] - ref[t]) / noise_sigma(t, ref[t]) for t in CMP_TAGS)
                L.append('      end of hold at lever %5.1f (%s): largest difference to sim.py at that second\'s '
                         'ambient = %.3f noise sigma (ambient drifts slowly, so not exactly steady)'
                         % (lev, stamp(te), frac))
            k += 1
    write_csv(os.path.join(OUTDIR, 'operations_voyages.csv'),
              ['voyage', 'kind', 'start_cmd', 'warmup_end', 'fuel_off', 'stopped', 'T_AMB_C_at_start',
               'P_AMB_KPA_at_start', 'lever_programme'] + ['true_' + d for d in DNAMES]
              + ['max_beta', 'min_pressure_rise_margin_pct', 'note'], vrows)
    sz = os.path.getsize(os.path.join(OUTDIR, 'operations_log.csv')) / 1e6
    szt = os.path.getsize(os.path.join(OUTDIR, 'operations_truth.csv')) / 1e6
    okv = all(v['max_beta'] < 0.95 and v['min_sm'] > 2.0 for v in voy)
    L.append('   file sizes: operations_log.csv %.1f MB, operations_truth.csv %.1f MB; no surge in any voyage %s'
             % (sz, szt, 'PASS' if okv else 'FAIL'))
    allok = allok and okv
    L.append('')
    idle = [(T0c, idle_point(T0c + 273.15, sim.ISO_P0)) for T0c in (-5.0, 15.0, 35.0)]
    write_dynamics(voy, idle)
    L.append('6. Summary: %s' % ('ALL PASS' if allok else 'SOME CHECKS FAILED'))
    L.append('   gas-path evaluations %d, Jacobians %d (wall time is printed on stdout only, to keep this'
             % (STATS['evals'], STATS['jac']))
    L.append('   file deterministic)')
    with open(os.path.join(OUTDIR, 'checks_dyn.txt'), 'w') as fh:
        fh.write('\n'.join(L) + '\n')
    print('\n'.join(L))
    print('wall time %.1f s' % (time.time() - T_START))


if __name__ == '__main__':
    main()
