#!/usr/bin/env python3
# -*- coding: utf-8 -*-
"""
indep3 -- independent "other maker" blind test data for a gas-turbine diagnostics tool.

Engine: marine two-shaft aero-derivative gas turbine ("MGT-25"), ~25 MW at ISO,
single-spool 16-stage gas-generator compressor (PR ~22, ~70 kg/s, 9500 rpm) with
variable stator vanes and a mid-compressor handling bleed, annular combustor on
marine gas oil, two-stage cooled HP turbine, inter-turbine duct, free power
turbine (3600 rpm) driving a controllable-pitch propeller via a reduction gear.

Everything (maps, losses, schedules, numbers) is an independent construction from
textbook physics (Saravanamuttoo et al., Walsh & Fletcher, Kurzke).

Run:  python3 sim.py      (Python 3 standard library only, deterministic)
Writes into this folder: design.txt, baseline_exact.csv, baseline_noisy.csv,
baseline_internal.csv, grid_exact.csv, grid_noisy.csv, grid_internal.csv, checks.txt
(README.md is hand-written and not touched).
"""
import math
import os
import random
import time

OUT = os.path.dirname(os.path.abspath(__file__))
T_START = time.time()

TREF, PREF = 288.15, 101.325      # reference for corrected parameters (K, kPa)
RU = 8.31446261815324             # J/(mol K)

# =============================================================================
# 0. ENGINE DESIGN CHOICES (all ours)
# =============================================================================
ISO_T0, ISO_P0 = 288.15, 101.325  # ISO 3977 ambient (dry air in this model)
NGG_D = 9500.0          # rpm   GG speed at ISO rating = 100 % corrected speed
NPT_D = 3600.0          # rpm   PT design speed (100 % on the combinator)
W2_D = 70.0             # kg/s  compressor inlet mass flow at ISO rating
PR_D = 22.0             # -     P3/P2 at ISO rating
BETA_D = 0.50           # -     design point sits mid-way on the 100 % speed line
ETA_C_D = 0.860         # -     compressor isentropic efficiency at rating
ETA_H_D = 0.875         # -     HPT isentropic (stage-by-stage, cooled) efficiency
ETA_P_D = 0.905         # -     PT isentropic efficiency (total-to-total)
SHP_D = 25000.0e3       # W     rated shaft power at the torque meter (PT output shaft)

X25 = 0.45              # handling-bleed port (after stage 8 of 16): ln(P25/P2) = X25 ln(P3/P2)

# Secondary air, fractions of compressor DELIVERY flow W3 (all bled at compressor exit, T3/P3)
COOL_NGV1 = 0.070       # HPT stage-1 nozzle cooling: mixes before rotor 1 (defines T41 = SOT)
COOL_ROT1 = 0.045       # HPT stage-1 rotor cooling: mixes between stage 1 and stage 2 (works in stage 2)
COOL_ST2 = 0.035        # HPT stage-2 nozzle+rotor cooling: mixes at HPT exit (does no HPT work)
LEAK = 0.005            # CDP seal leakage dumped overboard

# Pressure-loss coefficients: dP/P at rating, scaled with (corrected flow / rating)^2
K_IN = 0.010            # inlet filter/duct/plenum: P2 = P0 / (1 + K_IN (W2c/W2c_d)^2)
K_CC = 0.045            # combustor (liner + diffuser)
K_ITD = 0.015           # inter-turbine duct (HPT exit -> PT inlet)
K_EX = 0.025            # exhaust collector/uptake/silencer back-pressure: P5 = P0 (1 + K_EX (W5c/W5c_d)^2)

# Combustion: C12H23 marine gas oil
FUEL_C, FUEL_H = 12, 23
LHV = 42.7e6            # J/kg
T_FUEL, CP_FUEL = 313.15, 2000.0   # fuel delivered at 40 C, liquid cp (sensible part, small)
ETA_B_LOSS_D = 0.0015   # 1 - combustion efficiency at rating; grows with combustor loading

# Mechanical losses
MECH_GG = 0.005         # GG bearings/windage, fraction of HPT power
P_ACC_D = 90.0e3        # W, accessory gearbox (fuel, lube, hydraulic pumps) ~ NGG^3
MECH_PT = 0.002         # PT bearings, fraction of PT power
P_PTLOSS_D = 45.0e3     # W, PT windage/thrust bearing ~ NPT^2 (upstream of the torque meter)

# Variable stator vanes (IGV + stator rows 1..6), angle in degrees CLOSED from the full-open stop
VSV_MAX, VSV_N_OPEN, VSV_N_SHUT = 35.0, 0.95, 0.75
VSV_KW, VSV_KPR, VSV_KETA = 0.0055, 0.0030, 3.0e-5   # per deg / per deg / per deg^2 (see comp_map)

# Handling bleed valve (stage-8 port, dumped overboard), fraction of compressor inlet flow
BLEED_MAX, BLEED_N_OPEN, BLEED_N_SHUT = 0.06, 0.76, 0.88
BLEED_FRONT = 0.5       # front-block unthrottling: inlet flow x (1 + BLEED_FRONT*b) at a map point

# Turbine map constants
HPT_FC_EXP = 3.0        # HPT flow function sqrt(1 - PR^-n) (nozzle nearly choked)
HPT_FC_N = 0.02         # HPT flow capacity falls 2 % per 100 % corrected-speed increase
HPT_KNU, HPT_NUOPT = 0.55, 1.04
PT_FC_EXP = 2.0         # PT: Stodola ellipse law
PT_FC_N = 0.03
PT_KNU, PT_NUOPT = 0.45, 1.03

# Control limits
T54_MARGIN = 20.0       # K: max continuous T54 = T54 at ISO rating + 20 K
NGG_MAX = 10100.0       # rpm physical GG overspeed governor
NC_MAX = 1.045          # corrected GG speed topping limit

# Combinator (bridge lever -> PT speed fraction, pitch fraction of design pitch)
COMB_LEVER = [0, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100]
COMB_N = [0.60, 0.60, 0.60, 0.60, 0.6667, 0.7333, 0.80, 0.8667, 0.9333, 1.00, 1.00]
COMB_PITCH = [0.00, 0.30, 0.55, 0.78, 0.82, 0.85, 0.875, 0.895, 0.915, 0.93, 1.00]
PROP_Q0 = 0.09          # zero-pitch torque coefficient (fraction of design)

# =============================================================================
# 1. GAS PROPERTIES: NASA 7-coefficient polynomials (GRI-Mech 3.0 / Burcat data)
#    Sensible enthalpy referenced to 298.15 K; fuel chemistry enters through LHV.
#    A gas stream is (Wa, Wf): dry air mass flow and burnt-fuel mass flow.  Since
#    product composition is linear in FAR, the mixture polynomial is
#    (A + f*B)/(1+f), A = 1 kg of air, B = change per kg fuel burnt
#    (+12 CO2 + 11.5 H2O - 17.75 O2 per mole C12H23).
# =============================================================================
# coefficient order a1..a7; (low range [200/300, 1000 K], high range [1000, 3500/5000 K])
_NASA = {
    'N2': ([3.298677, 1.4082404e-3, -3.963222e-6, 5.641515e-9, -2.444854e-12, -1020.8999, 3.950372],
           [2.92664, 1.4879768e-3, -5.68476e-7, 1.0097038e-10, -6.753351e-15, -922.7977, 5.980528]),
    'O2': ([3.78245636, -2.99673416e-3, 9.84730201e-6, -9.68129509e-9, 3.24372837e-12, -1063.94356, 3.65767573],
           [3.28253784, 1.48308754e-3, -7.57966669e-7, 2.09470555e-10, -2.16717794e-14, -1088.45772, 5.45323129]),
    'AR': ([2.5, 0.0, 0.0, 0.0, 0.0, -745.375, 4.366],
           [2.5, 0.0, 0.0, 0.0, 0.0, -745.375, 4.366]),
    'CO2': ([2.35677352, 8.98459677e-3, -7.12356269e-6, 2.45919022e-9, -1.43699548e-13, -48371.9697, 9.90105222],
            [3.85746029, 4.41437026e-3, -2.21481404e-6, 5.23490188e-10, -4.72084164e-14, -48759.1660, 2.27163806]),
    'H2O': ([4.19864056, -2.03643410e-3, 6.52040211e-6, -5.48797062e-9, 1.77197817e-12, -30293.7267, -0.849032208],
            [3.03399249, 2.17691804e-3, -1.64072518e-7, -9.70419870e-11, 1.68200992e-14, -30004.2971, 4.96677010]),
}
_MM = {'N2': 28.0134e-3, 'O2': 31.9988e-3, 'AR': 39.948e-3, 'CO2': 44.0095e-3, 'H2O': 18.01528e-3}
_AIR_X = {'N2': 0.78084, 'O2': 0.209476, 'AR': 0.00934, 'CO2': 0.000314}   # dry air, mole fractions
TMID = 1000.0


def _h_poly(a, T):   # h/R (K), including a6
    return T * (a[0] + T * (a[1] / 2 + T * (a[2] / 3 + T * (a[3] / 4 + T * a[4] / 5)))) + a[5]


def _s_poly(a, T):   # s/R
    return a[0] * math.log(T) + T * (a[1] + T * (a[2] / 2 + T * (a[3] / 3 + T * a[4] / 4))) + a[6]


# Make each species exactly continuous in h and s at 1000 K (the published fits jump slightly;
# a jump would make the Newton residuals discontinuous).  Adjust high-range a6, a7.
for _sp, (_lo, _hi) in _NASA.items():
    _hi[5] += _h_poly(_lo, TMID) - _h_poly(_hi, TMID)
    _hi[6] += _s_poly(_lo, TMID) - _s_poly(_hi, TMID)

_xs = sum(_AIR_X.values())
_AIR_X = {k: v / _xs for k, v in _AIR_X.items()}
M_AIR = sum(_AIR_X[k] * _MM[k] for k in _AIR_X)
M_FUEL = FUEL_C * 12.0107e-3 + FUEL_H * 1.00794e-3
N_O2_STOICH = FUEL_C + FUEL_H / 4.0
FAR_STOICH = M_FUEL / (N_O2_STOICH / _AIR_X['O2'] * M_AIR)

# mol per kg for the two "pseudo-species": A (1 kg air) and B (per kg fuel burnt)
_nA = {k: _AIR_X[k] / M_AIR for k in _AIR_X}
_nB = {'CO2': FUEL_C / M_FUEL, 'H2O': (FUEL_H / 2.0) / M_FUEL, 'O2': -N_O2_STOICH / M_FUEL}


def _combine(nmol):
    lo = [0.0] * 7
    hi = [0.0] * 7
    for sp, n in nmol.items():
        for k in range(7):
            lo[k] += RU * n * _NASA[sp][0][k]
            hi[k] += RU * n * _NASA[sp][1][k]
    return lo, hi, RU * sum(nmol.values())


_A_LO, _A_HI, _A_R = _combine(_nA)
_B_LO, _B_HI, _B_R = _combine(_nB)


class Gas:
    """Ideal gas with a fixed composition; enthalpy is sensible (0 at 298.15 K), J/kg."""
    __slots__ = ('lo', 'hi', 'R', 'href', 'hlo', 'hhi', 'slo', 'shi')

    def __init__(self, lo, hi, R):
        self.lo, self.hi, self.R = lo, hi, R
        self.hlo = [lo[0], lo[1] / 2, lo[2] / 3, lo[3] / 4, lo[4] / 5, lo[5]]
        self.hhi = [hi[0], hi[1] / 2, hi[2] / 3, hi[3] / 4, hi[4] / 5, hi[5]]
        self.slo = [lo[0], lo[1], lo[2] / 2, lo[3] / 3, lo[4] / 4, lo[6]]
        self.shi = [hi[0], hi[1], hi[2] / 2, hi[3] / 3, hi[4] / 4, hi[6]]
        self.href = 0.0
        self.href = self.h(298.15)

    def h(self, T):
        a = self.hlo if T < TMID else self.hhi
        return T * (a[0] + T * (a[1] + T * (a[2] + T * (a[3] + T * a[4])))) + a[5] - self.href

    def cp(self, T):
        a = self.lo if T < TMID else self.hi
        return a[0] + T * (a[1] + T * (a[2] + T * (a[3] + T * a[4])))

    def phi(self, T):      # entropy function s0(T) (J/kg/K), constant mixing terms dropped
        a = self.slo if T < TMID else self.shi
        return a[0] * math.log(T) + T * (a[1] + T * (a[2] + T * (a[3] + T * a[4]))) + a[5]

    def T_h(self, h, T):
        for _ in range(50):
            dT = (self.h(T) - h) / self.cp(T)
            T -= dT
            if abs(dT) < 1e-10 * T:
                return T
        raise ValueError('T_h did not converge')

    def T_phi(self, phi, T):
        for _ in range(50):
            dT = (self.phi(T) - phi) * T / self.cp(T)
            T -= dT
            if abs(dT) < 1e-10 * T:
                return T
        raise ValueError('T_phi did not converge')


AIR = Gas(_A_LO, _A_HI, _A_R)
FUELB = Gas(_B_LO, _B_HI, _B_R)      # per kg fuel burnt (can be negative-valued, used in sums only)
H_FUEL = CP_FUEL * (T_FUEL - 298.15)  # sensible enthalpy of liquid fuel, J/kg


def gas_f(f):
    """Combustion products of dry air + C12H23 at fuel/air ratio f (per kg mixture)."""
    if f == 0.0:
        return AIR
    k = 1.0 / (1.0 + f)
    return Gas([(a + f * b) * k for a, b in zip(_A_LO, _B_LO)],
               [(a + f * b) * k for a, b in zip(_A_HI, _B_HI)],
               (_A_R + f * _B_R) * k)


def stream_H(Wa, Wf, T):
    """Enthalpy flux (W) of a stream of Wa kg/s air + Wf kg/s burnt fuel at T."""
    return Wa * AIR.h(T) + Wf * FUELB.h(T)


def mix(streams, Tguess):
    """Adiabatic constant-pressure mixing of streams [(Wa, Wf, T), ...] -> (Wa, Wf, T, gas)."""
    H = sum(stream_H(a, f, t) for a, f, t in streams)
    Wa = sum(s[0] for s in streams)
    Wf = sum(s[1] for s in streams)
    g = gas_f(Wf / Wa)
    return Wa, Wf, g.T_h(H / (Wa + Wf), Tguess), g


def expand(g, T1, PR, eta_fn):
    """Turbine expansion over pressure ratio PR; eta_fn(dh_is) gives the efficiency."""
    h1 = g.h(T1)
    T2s = g.T_phi(g.phi(T1) - g.R * math.log(PR), T1 * PR ** -0.25)
    dhis = h1 - g.h(T2s)
    eta = eta_fn(dhis)
    T2 = g.T_h(h1 - eta * dhis, T2s)
    return T2, eta * dhis, dhis, eta


# =============================================================================
# 2. SCHEDULES AND COMPONENT MAPS
# =============================================================================
def smoothstep(x):
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return x * x * (3.0 - 2.0 * x)


def vsv_angle(nc):
    """VSV closure (deg from full-open stop) scheduled on corrected GG speed (fraction)."""
    return VSV_MAX * smoothstep((VSV_N_OPEN - nc) / (VSV_N_OPEN - VSV_N_SHUT))


def bleed_frac(nc):
    """Handling-bleed flow as fraction of compressor inlet flow, scheduled on corrected speed."""
    return BLEED_MAX * (1.0 - smoothstep((nc - BLEED_N_OPEN) / (BLEED_N_SHUT - BLEED_N_OPEN)))


def comp_map(N, beta):
    """Unscaled compressor characteristic.  N = corrected speed / design, beta in [0 choke, 1 surge].

    Base ('open-vane') speed lines: flow linear in beta between a surge-line flow ws(N) and a
    choke flow ws+dw (dw widens at part speed); pressure rise (PR-1) is maximal (zero slope)
    at surge and drops towards choke, so high-speed lines are near-vertical, low-speed lines
    flatter.  Surge line: (PR-1) ~ ws^1.35.  Efficiency: peak island at beta~0.62 near
    N~0.96, falling faster towards choke than towards surge and above 100 % speed.

    VSV closure theta (deg): pre-swirl from the IGV/VSVs reduces the axial velocity at which
    the front rotors reach their design incidence (flow x (1 - 0.0055 theta)), reduces the
    Euler work of the front stages (PR-1 x (1 - 0.0030 theta)), and adds vane turning/
    incidence loss (eta - 3e-5 theta^2).  Handling bleed b unthrottles the front block:
    inlet flow x (1 + 0.5 b) at a given map position.
    """
    ws = 0.965 * N ** 1.75
    dw = 0.065 + 0.20 * max(0.0, 1.0 - N) ** 1.5
    w = ws + dw * (1.0 - beta)
    prs = 23.5 * (ws / 0.965) ** 1.35
    prm1 = prs * (1.0 - 0.45 * (1.0 - beta) ** 2)
    dn = N - 0.96
    eta = 0.872 - 0.30 * dn * dn - (1.5 * (N - 1.0) ** 2 if N > 1.0 else 0.0)
    db = beta - 0.62
    eta -= (0.20 if db < 0.0 else 0.12) * db * db
    th = vsv_angle(N)
    b = bleed_frac(N)
    w *= (1.0 - VSV_KW * th) * (1.0 + BLEED_FRONT * b)
    fpr = 1.0 - VSV_KPR * th
    prm1 *= fpr
    prs *= fpr
    eta -= VSV_KETA * th * th
    return w, prm1, eta, th, b, prs


def hpt_fc(PR, Nh, PRd):
    """HPT flow capacity relative to design: nearly-choked nozzle, generalized ellipse."""
    g = math.sqrt(1.0 - PR ** -HPT_FC_EXP)
    gd = math.sqrt(1.0 - PRd ** -HPT_FC_EXP)
    return g / gd * (1.0 - HPT_FC_N * (Nh - 1.0))


def pt_fc(PR, Np, PRd):
    """PT flow capacity relative to design: Stodola ellipse law + small speed effect."""
    g = math.sqrt(1.0 - PR ** -PT_FC_EXP)
    gd = math.sqrt(1.0 - PRd ** -PT_FC_EXP)
    return g / gd * (1.0 - PT_FC_N * (Np - 1.0))


def turb_eta_rel(nu, k, nuopt):
    """Efficiency vs blade-speed ratio nu = (U/C0)/(U/C0)_design, =1 at nu=1."""
    return (1.0 - k * (nu - nuopt) ** 2) / (1.0 - k * (1.0 - nuopt) ** 2)


# =============================================================================
# 3. COMPONENT THERMODYNAMICS (shared by the design sizing and the off-design cycle)
# =============================================================================
def compressor(T2, P2, W2, PR, eta, b):
    h2 = AIR.h(T2)
    phi2 = AIR.phi(T2)
    T3s = AIR.T_phi(phi2 + AIR.R * math.log(PR), T2 * PR ** 0.2857)
    h3 = h2 + (AIR.h(T3s) - h2) / eta
    T3 = AIR.T_h(h3, T3s)
    # polytropic efficiency consistent with (PR, eta) for the real gas; the stage-8 state
    # (bleed port) lies on the same polytropic path
    eta_p = AIR.R * math.log(PR) / (AIR.phi(T3) - phi2)
    PR25 = PR ** X25
    T25 = AIR.T_phi(phi2 + AIR.R * math.log(PR25) / eta_p, T2 * PR25 ** 0.3)
    h25 = AIR.h(T25)
    Wb = b * W2
    Pw = W2 * (h25 - h2) + (W2 - Wb) * (h3 - h25)   # bled air did the front-block work only
    return dict(T3=T3, P3=P2 * PR, T25=T25, P25=P2 * PR25, h25=h25, h3=h3, Wb=Wb,
                Pcomp=Pw, eta_p=eta_p, W3=W2 - Wb)


def hot_section(c, T4, PRh, eta_h_fn, Wcc_frac=None):
    """Combustor exit -> HPT exit (station 48) for given T4 and HPT pressure ratio."""
    W3, T3, P3 = c['W3'], c['T3'], c['P3']
    W_ngv, W_r1, W_s2, W_lk = W3 * COOL_NGV1, W3 * COOL_ROT1, W3 * COOL_ST2, W3 * LEAK
    Wcc = W3 - W_ngv - W_r1 - W_s2 - W_lk
    # combustor loading parameter (Lefebvre-type), normalised later by its rating value
    omega = Wcc / (P3 ** 1.75 * math.exp(T3 / 300.0))
    eta_b = 1.0 - ETA_B_LOSS_D * omega / DES['omega'] if 'omega' in DES else 1.0 - ETA_B_LOSS_D
    # energy: Wcc hA(T3) + WF (eta_b LHV + h_fuel) = Wcc hA(T4) + WF hB(T4)
    far = (AIR.h(T4) - AIR.h(T3)) / (eta_b * LHV + H_FUEL - FUELB.h(T4))
    WF = far * Wcc
    Wc3 = Wcc * math.sqrt(T3) / P3
    P4 = P3 * (1.0 - K_CC * (Wc3 / DES['Wc3']) ** 2) if 'Wc3' in DES else P3 * (1.0 - K_CC)
    # NGV-1 cooling mixes before rotor 1 -> T41 (stator outlet / rotor inlet temperature)
    Wa41, Wf41, T41, g41 = mix([(Wcc, WF, T4), (W_ngv, 0.0, T3)], T4 - 40.0)
    W41, P41 = Wa41 + Wf41, P4
    # total isentropic drop (for the blade-speed-ratio) -> efficiency used for both stages
    T48s = g41.T_phi(g41.phi(T41) - g41.R * math.log(PRh), T41 * PRh ** -0.25)
    dhis = g41.h(T41) - g41.h(T48s)
    eta_h = eta_h_fn(dhis)
    PR1 = math.sqrt(PRh)          # equal pressure-ratio split between the two stages
    Tm, dh1, _, _ = expand(g41, T41, PR1, lambda d: eta_h)
    Wam, Wfm, Tm2, gm = mix([(Wa41, Wf41, Tm), (W_r1, 0.0, T3)], Tm - 20.0)
    T45, dh2, _, _ = expand(gm, Tm2, PR1, lambda d: eta_h)
    P_hpt = W41 * dh1 + (Wam + Wfm) * dh2
    Wa48, Wf48, T48, g48 = mix([(Wam, Wfm, T45), (W_s2, 0.0, T3)], T45 - 20.0)
    return dict(Wcc=Wcc, W_ngv=W_ngv, W_r1=W_r1, W_s2=W_s2, W_leak=W_lk, omega=omega, eta_b=eta_b,
                far=far, WF=WF, Wc3=Wc3, P4=P4, T4=T4, T41=T41, W41=W41, P41=P41, f41=Wf41 / Wa41,
                dhis_h=dhis, eta_h=eta_h, T45=T45, P_hpt=P_hpt, Wa48=Wa48, Wf48=Wf48, T48=T48,
                P48=P41 / PRh, g48=g48, PRh=PRh, Tmid=Tm2, Pmid=P41 / PR1)


def gg_losses(P_hpt, NGG):
    return MECH_GG * P_hpt + P_ACC_D * (NGG / NGG_D) ** 3


def pt_losses(P_pt, NPT):
    return MECH_PT * P_pt + P_PTLOSS_D * (NPT / NPT_D) ** 2


# =============================================================================
# 4. DESIGN-POINT SIZING at ISO (map scaling, turbine flow capacities, references)
# =============================================================================
DES = {}


def size_design():
    T0, P0 = ISO_T0, ISO_P0
    T2, P2 = T0, P0 / (1.0 + K_IN)
    W2 = W2_D
    W2c = W2 * math.sqrt(T2 / TREF) / (P2 / PREF)
    c = compressor(T2, P2, W2, PR_D, ETA_C_D, 0.0)
    P5 = P0 * (1.0 + K_EX)

    def hot(T4):
        # find HPT pressure ratio that balances the GG shaft (secant)
        def bal(PRh):
            s = hot_section(c, T4, PRh, lambda d: ETA_H_D)
            return s['P_hpt'] - gg_losses(s['P_hpt'], NGG_D) - c['Pcomp'], s
        a, b = 3.0, 4.5
        fa, fb = bal(a)[0], bal(b)[0]
        for _ in range(60):
            x = b - fb * (b - a) / (fb - fa)
            a, fa = b, fb
            b = x
            fb, s = bal(b)
            if abs(fb) < 1e-6:
                break
        W48 = s['Wa48'] + s['Wf48']
        P54 = s['P48'] * (1.0 - K_ITD)
        T54 = s['T48']
        PRp = P54 / P5
        T5, dhp, dhisp, _ = expand(s['g48'], T54, PRp, lambda d: ETA_P_D)
        P_pt = W48 * dhp
        SHP = P_pt - pt_losses(P_pt, NPT_D)
        return SHP, s, dict(W48=W48, P54=P54, T54=T54, PRp=PRp, T5=T5, dhisp=dhisp, P_pt=P_pt)

    a, b = 1550.0, 1650.0
    fa, fb = hot(a)[0] - SHP_D, hot(b)[0] - SHP_D
    for _ in range(60):
        x = b - fb * (b - a) / (fb - fa)
        a, fa = b, fb
        b = x
        r = hot(b)
        fb = r[0] - SHP_D
        if abs(fb) < 1e-4:
            break
    SHP, s, p = r
    m = comp_map(1.0, BETA_D)
    DES.update(
        W2c=W2c, sW=W2c / m[0], sPR=(PR_D - 1.0) / m[1], sE=ETA_C_D / m[2],
        T4=s['T4'], PRh=s['PRh'], PRp=p['PRp'],
        FC41=s['W41'] * math.sqrt(s['T41']) / s['P41'], Nh=NGG_D / math.sqrt(s['T41']),
        dhis_h=s['dhis_h'], Wc3=s['Wc3'], omega=s['omega'],
        Wc48=p['W48'] * math.sqrt(s['T48']) / s['P48'],
        FC54=p['W48'] * math.sqrt(p['T54']) / p['P54'], Np=NPT_D / math.sqrt(p['T54']),
        dhis_p=p['dhisp'], Wc5=p['W48'] * math.sqrt(p['T5']) / P0,
        Pcomp=c['Pcomp'], T54=p['T54'])
    DES['T54_MAX'] = DES['T54'] + T54_MARGIN


# =============================================================================
# 5. OFF-DESIGN CYCLE: unknowns x = [Nc, beta, T4/T4d, PRh/PRhd, PRp/PRpd]
#    residuals: HPT flow capacity, GG power balance, PT flow capacity, exhaust
#    back-pressure, and the load (SHP = demand) or an active control limit.
# =============================================================================
def cycle(x, T0, P0, NPT, deg, mode='SHP', target=None, full=False):
    N, beta, t4r, phr, ppr = x
    PRh, PRp, T4 = phr * DES['PRh'], ppr * DES['PRp'], t4r * DES['T4']
    if not (0.45 < N < 1.25) or PRh < 1.02 or PRp < 1.005 or not (500.0 < T4 < 2300.0) \
            or not (-0.8 < beta < 1.8):
        raise ValueError('out of domain')
    dgc, dec, dgt, det, dgp, dep = deg
    # --- inlet and compressor
    w, prm1, eta, th, b, prs = comp_map(N, beta)
    W2c = DES['sW'] * w * (1.0 - dgc / 100.0)
    PR = 1.0 + DES['sPR'] * prm1
    eta_c = DES['sE'] * eta * (1.0 - dec / 100.0)
    T2 = T0
    P2 = P0 / (1.0 + K_IN * (W2c / DES['W2c']) ** 2)
    W2 = W2c * (P2 / PREF) / math.sqrt(T2 / TREF)
    NGG = N * NGG_D * math.sqrt(T2 / TREF)
    if PR <= 1.05 or eta_c <= 0.3:
        raise ValueError('compressor out of domain')
    c = compressor(T2, P2, W2, PR, eta_c, b)

    # --- combustor + HPT
    def eta_h_fn(dhis):
        nu = (NGG / NGG_D) / math.sqrt(dhis / DES['dhis_h'])
        return ETA_H_D * turb_eta_rel(nu, HPT_KNU, HPT_NUOPT) * (1.0 - det / 100.0)
    s = hot_section(c, T4, PRh, eta_h_fn)
    if s['far'] <= 0.0:
        raise ValueError('negative fuel')
    Nh = (NGG / math.sqrt(s['T41'])) / DES['Nh']
    fc41 = s['W41'] * math.sqrt(s['T41']) / s['P41']
    r1 = fc41 / (DES['FC41'] * hpt_fc(PRh, Nh, DES['PRh']) * (1.0 - dgt / 100.0)) - 1.0
    loss_gg = gg_losses(s['P_hpt'], NGG)
    r2 = (s['P_hpt'] - loss_gg - c['Pcomp']) / DES['Pcomp']
    # --- inter-turbine duct
    W48, T48, P48 = s['Wa48'] + s['Wf48'], s['T48'], s['P48']
    Wc48 = W48 * math.sqrt(T48) / P48
    P54 = P48 * (1.0 - K_ITD * (Wc48 / DES['Wc48']) ** 2)
    T54 = T48
    # --- power turbine
    Np = (NPT / math.sqrt(T54)) / DES['Np']
    fc54 = W48 * math.sqrt(T54) / P54
    r3 = fc54 / (DES['FC54'] * pt_fc(PRp, Np, DES['PRp']) * (1.0 - dgp / 100.0)) - 1.0
    nu_p = [0.0]

    def eta_p_fn(dhis):
        nu_p[0] = (NPT / NPT_D) / math.sqrt(dhis / DES['dhis_p'])
        return ETA_P_D * turb_eta_rel(nu_p[0], PT_KNU, PT_NUOPT) * (1.0 - dep / 100.0)
    T5, dhp, dhisp, eta_p = expand(s['g48'], T54, PRp, eta_p_fn)
    P5 = P54 / PRp
    Wc5 = W48 * math.sqrt(T5) / P0
    P5req = P0 * (1.0 + K_EX * (Wc5 / DES['Wc5']) ** 2)
    r4 = P5 / P5req - 1.0
    P_pt = W48 * dhp
    loss_pt = pt_losses(P_pt, NPT)
    SHP = P_pt - loss_pt
    if mode == 'SHP':
        r5 = SHP / target - 1.0
    elif mode == 'T54':
        r5 = T54 / target - 1.0
    elif mode == 'NGG':
        r5 = NGG / target - 1.0
    elif mode == 'NC':
        r5 = N / target - 1.0
    else:
        raise KeyError(mode)
    r = [r1, r2, r3, r4, r5]
    if not full:
        return r
    # ---- full state for output and checks
    nu_h = (NGG / NGG_D) / math.sqrt(s['dhis_h'] / DES['dhis_h'])
    W5 = W48
    # global energy balance (sensible enthalpy + heat released), should close to round-off
    E_in = W2 * AIR.h(T2) + s['WF'] * (s['eta_b'] * LHV + H_FUEL)
    E_out = (SHP + loss_pt + loss_gg + c['Wb'] * c['h25'] + s['W_leak'] * c['h3']
             + stream_H(s['Wa48'], s['Wf48'], T5))
    M_in = W2 + s['WF']
    M_out = W5 + c['Wb'] + s['W_leak']
    st = dict(
        T0=T0, P0=P0, T2=T2, P2=P2, N=N, beta=beta, NGG=NGG, NPT=NPT, vsv=th, bleed=b,
        W2=W2, W2c=W2c, PR=PR, eta_c=eta_c, eta_cp=c['eta_p'], PRsurge=1.0 + DES['sPR'] * prs,
        SM=((1.0 + DES['sPR'] * prs) / PR - 1.0) * 100.0,
        T25=c['T25'], P25=c['P25'], Wbleed=c['Wb'], T3=c['T3'], P3=c['P3'], W3=c['W3'],
        Wcool=s['W_ngv'] + s['W_r1'] + s['W_s2'], Wleak=s['W_leak'], Wcc=s['Wcc'],
        eta_b=s['eta_b'], far=s['far'], WF=s['WF'], T4=T4, P4=s['P4'], T41=s['T41'], W41=s['W41'],
        PRh=PRh, eta_h=s['eta_h'], nu_h=nu_h, FC41=fc41, T48=T48, P48=P48, W48=W48,
        T54=T54, P54=P54, PRp=PRp, eta_p=eta_p, nu_p=nu_p[0], FC54=fc54, T5=T5, P5=P5, W5=W5,
        Pcomp=c['Pcomp'], Phpt=s['P_hpt'], Ppt=P_pt, loss_gg=loss_gg, loss_pt=loss_pt, SHP=SHP,
        HR=3600.0 * s['WF'] * LHV / SHP if SHP > 0 else float('nan'),
        eta_th=SHP / (s['WF'] * LHV) if s['WF'] > 0 else float('nan'),
        e_close=(E_in - E_out) / (s['WF'] * LHV), m_close=(M_in - M_out) / M_in,
        res=max(abs(v) for v in r))
    return r, st


# =============================================================================
# 6. NEWTON SOLVER (finite-difference Jacobian, step limiting, backtracking)
# =============================================================================
def linsolve(A, b):
    n = len(b)
    M = [row[:] + [b[i]] for i, row in enumerate(A)]
    for k in range(n):
        p = max(range(k, n), key=lambda i: abs(M[i][k]))
        if abs(M[p][k]) < 1e-300:
            raise ZeroDivisionError('singular Jacobian')
        M[k], M[p] = M[p], M[k]
        for i in range(k + 1, n):
            f = M[i][k] / M[k][k]
            if f != 0.0:
                for j in range(k, n + 1):
                    M[i][j] -= f * M[k][j]
    xs = [0.0] * n
    for i in range(n - 1, -1, -1):
        xs[i] = (M[i][n] - sum(M[i][j] * xs[j] for j in range(i + 1, n))) / M[i][i]
    return xs


STEP_LIM = [0.04, 0.25, 0.08, 0.15, 0.20]
STATS = {'cycles': 0}


def newton(fun, x0, tol=1e-10, maxit=60):
    x = list(x0)

    def ev(xx):
        STATS['cycles'] += 1
        try:
            return fun(xx)
        except (ValueError, ZeroDivisionError, OverflowError):
            return None
    r = ev(x)
    if r is None:
        return None
    nr = math.sqrt(sum(v * v for v in r))
    for it in range(maxit):
        if max(abs(v) for v in r) < tol:
            return x, it
        J = [[0.0] * 5 for _ in range(5)]
        for j in range(5):
            hstep = 1e-7 * max(1.0, abs(x[j]))
            xp = x[:]
            xp[j] += hstep
            rp = ev(xp)
            if rp is None:
                xp[j] = x[j] - hstep
                rp = ev(xp)
                if rp is None:
                    return None
                hstep = -hstep
            for i in range(5):
                J[i][j] = (rp[i] - r[i]) / hstep
        try:
            dx = linsolve(J, [-v for v in r])
        except ZeroDivisionError:
            return None
        s = 1.0
        for i in range(5):
            if abs(dx[i]) > STEP_LIM[i]:
                s = min(s, STEP_LIM[i] / abs(dx[i]))
        alpha = s
        for _ in range(20):
            xn = [x[i] + alpha * dx[i] for i in range(5)]
            rn = ev(xn)
            if rn is not None:
                nrn = math.sqrt(sum(v * v for v in rn))
                if nrn < (1.0 - 1e-4 * alpha) * nr or max(abs(v) for v in rn) < tol:
                    break
            alpha *= 0.5
        else:
            return None
        x, r, nr = xn, rn, nrn
    return None


# =============================================================================
# 7. COMBINATOR, OPERATING-POINT SOLUTION WITH LIMITS, CONTINUATION
# =============================================================================
def interp(x, xs, ys):
    if x <= xs[0]:
        return ys[0]
    for i in range(1, len(xs)):
        if x <= xs[i]:
            t = (x - xs[i - 1]) / (xs[i] - xs[i - 1])
            return ys[i - 1] + t * (ys[i] - ys[i - 1])
    return ys[-1]


def combinator(lever):
    """Bridge lever (%) -> (PT speed fraction, pitch fraction, demanded SHP fraction).
    Propeller absorption on the schedule: P/P_d = n^3 * Q(p), Q = Q0 + (1-Q0) p^1.5."""
    n = interp(lever, COMB_LEVER, COMB_N)
    p = interp(lever, COMB_LEVER, COMB_PITCH)
    return n, p, n ** 3 * (PROP_Q0 + (1.0 - PROP_Q0) * p ** 1.5)


def lever_for_power(pf):
    lo, hi = 0.0, 100.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if combinator(mid)[2] < pf:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


ISO_LINE = []     # (corrected power fraction, x) along the ISO combinator line, for guesses


def build_iso_line():
    x = [1.0, BETA_D, 1.0, 1.0, 1.0]
    pts = [(1.0, x)]
    for up in (False, True):
        xc = x[:]
        pfs = [1.0 + 0.025 * k for k in range(1, 7)] if up else [1.0 - 0.025 * k for k in range(1, 35)]
        for pf in pfs:
            npt = combinator(lever_for_power(min(pf, 1.0)))[0] * NPT_D
            sol = newton(lambda xx: cycle(xx, ISO_T0, ISO_P0, npt, (0,) * 6, 'SHP', pf * SHP_D), xc)
            if sol is None:
                break
            xc = sol[0]
            pts.append((pf, xc))
    pts.sort(key=lambda t: t[0])
    ISO_LINE[:] = pts


def guess_x(T0, P0, shp):
    th, dl = T0 / TREF, P0 / PREF
    pc = shp / SHP_D / (dl * math.sqrt(th))
    xs = [p[0] for p in ISO_LINE]
    g = [interp(pc, xs, [p[1][i] for p in ISO_LINE]) for i in range(5)]
    g[2] *= th
    return g


def solve_mode(T0, P0, NPT, deg, mode, target, x0, depth=0, x_from=None, par_from=None):
    """Newton from x0; if it fails and a converged neighbour is known, march parameters
    (ambient, speed, target, degradation) from the neighbour in halving steps."""
    f = lambda xx: cycle(xx, T0, P0, NPT, deg, mode, target)
    sol = newton(f, x0)
    if sol is not None or x_from is None or depth > 6:
        return sol
    # continuation: par = (T0, P0, NPT, target, deg)
    p0 = par_from
    p1 = (T0, P0, NPT, target, deg)
    xcur = x_from
    nsteps = 4
    for k in range(1, nsteps + 1):
        t = k / nsteps
        pk = tuple(p0[i] + t * (p1[i] - p0[i]) for i in range(4))
        dk = tuple(p0[4][i] + t * (p1[4][i] - p0[4][i]) for i in range(6))
        fk = lambda xx, pk=pk, dk=dk: cycle(xx, pk[0], pk[1], pk[2], dk, mode, pk[3])
        s = newton(fk, xcur)
        if s is None:
            # split this step further
            pm = tuple(p0[i] + (k - 1) / nsteps * (p1[i] - p0[i]) for i in range(4))
            dm = tuple(p0[4][i] + (k - 1) / nsteps * (p1[4][i] - p0[4][i]) for i in range(6))
            s = solve_mode(pk[0], pk[1], pk[2], dk, mode, pk[3], xcur, depth + 1,
                           xcur, (pm[0], pm[1], pm[2], pm[3], dm))
            if s is None:
                return None
        xcur = s[0]
    return newton(f, xcur)


def solve_point(T0, P0, NPT, demand, deg, x0=None, x_from=None, par_from=None):
    """Steady point at demanded SHP; if a limit (T54, NGG, corrected NGG) would be exceeded the
    control holds that limit instead and power falls short of demand.  Returns (x, state, info)."""
    if x0 is None:
        x0 = guess_x(T0, P0, demand)
    if x_from is None:
        # neighbour for continuation: ISO at the same lever
        x_from = guess_x(ISO_T0, ISO_P0, demand)
        x_from = newton(lambda xx: cycle(xx, ISO_T0, ISO_P0, NPT, (0,) * 6, 'SHP', demand), x_from)
        x_from = x_from[0] if x_from else None
        par_from = (ISO_T0, ISO_P0, NPT, demand, (0.0,) * 6)
    sol = solve_mode(T0, P0, NPT, deg, 'SHP', demand, x0, 0, x_from, par_from)
    limits = (('T54', DES['T54_MAX']), ('NGG', NGG_MAX), ('NC', NC_MAX))
    if sol is not None:
        r, st = cycle(sol[0], T0, P0, NPT, deg, 'SHP', demand, full=True)
        viol = [(m, v) for m, v in limits if {'T54': st['T54'], 'NGG': st['NGG'], 'NC': st['N']}[m] > v]
        if not viol:
            st['limiter'] = 'none'
            st['iters'] = sol[1]
            return sol[0], st
        xl = sol[0]
    else:
        viol = list(limits)
        xl = x0
    best = None
    # continuation start for a limit mode: the neighbour's own value of the limited quantity
    par_lim = None
    if x_from is not None:
        stn = cycle(x_from, par_from[0], par_from[1], par_from[2], par_from[4], 'SHP', par_from[3], full=True)[1]
        par_lim = {'T54': stn['T54'], 'NGG': stn['NGG'], 'NC': stn['N']}
    for m, v in viol:
        pf = None if par_lim is None else (par_from[0], par_from[1], par_from[2], par_lim[m], par_from[4])
        s2 = solve_mode(T0, P0, NPT, deg, m, v, xl, 0, x_from if pf else None, pf)
        if s2 is None:
            continue
        r, st = cycle(s2[0], T0, P0, NPT, deg, m, v, full=True)
        ok = all({'T54': st['T54'], 'NGG': st['NGG'], 'NC': st['N']}[mm] <= vv * (1 + 1e-9)
                 for mm, vv in limits)
        if ok and st['SHP'] <= demand * (1 + 1e-9) and (best is None or st['SHP'] < best[1]['SHP']):
            st['limiter'] = m
            st['iters'] = s2[1]
            best = (s2[0], st)
    if best is None:
        raise RuntimeError('no solution at T0=%.2f P0=%.3f NPT=%.1f demand=%.0f deg=%s'
                           % (T0, P0, NPT, demand, deg))
    return best


# =============================================================================
# 8. TEST PROGRAMME: levers, days, degradation grid, noise
# =============================================================================
POWER_TARGETS = [0.30, 0.385, 0.47, 0.56, 0.65, 0.74, 0.83, 0.915, 1.00]
LEVERS = [round(lever_for_power(p) * 2.0) / 2.0 for p in POWER_TARGETS]
LEVERS[-1] = 100.0

# baseline days: one per lever (deg C, kPa); chosen to span -5..+35 C and 99..103 kPa,
# full lever deliberately on a warm day (T54-limited, see README)
BASE_DAYS = [(21.5, 100.10), (-4.5, 102.80), (33.5, 99.40), (9.0, 101.60), (27.0, 100.70),
             (1.5, 99.10), (15.5, 102.20), (-1.0, 101.00), (30.5, 100.40)]

# measured tags: (column, key-in-state, converter, 1-sigma noise, noise kind, rounding)
#   kind 'abs' = absolute sigma in the column unit; 'rel' = fraction of reading
K2C = lambda T: T - 273.15
TAGS = [
    ('T_AMB_C', 'T0', K2C, 0.3, 'abs', 1),
    ('P_AMB_KPA', 'P0', lambda v: v, 0.05, 'abs', 2),
    ('T2_C', 'T2', K2C, 0.5, 'abs', 1),
    ('P2_KPA', 'P2', lambda v: v, 0.0015, 'rel', 2),
    ('NGG_RPM', 'NGG', lambda v: v, 0.0005, 'rel', 1),
    ('NPT_RPM', 'NPT', lambda v: v, 0.0005, 'rel', 1),
    ('WF_KGH', 'WF', lambda v: v * 3600.0, 0.005, 'rel', 1),
    ('P3_KPA', 'P3', lambda v: v, 0.0015, 'rel', 1),
    ('T3_C', 'T3', K2C, 2.0, 'abs', 1),
    ('P54_KPA', 'P54', lambda v: v, 0.002, 'rel', 2),
    ('T54_C', 'T54', K2C, 3.0, 'abs', 1),
    ('T8_C', 'T5', K2C, 2.0, 'abs', 1),
    ('SHP_KW', 'SHP', lambda v: v / 1000.0, 0.005, 'rel', 0),
]
DNAMES = ['D_GC', 'D_EC', 'D_GT', 'D_ET', 'D_GP', 'D_EP']

INTERNAL = [
    ('lever_pct', 'lever', '%.2f'), ('shp_demand_kW', 'demand_kW', '%.3f'), ('limiter', 'limiter', '%s'),
    ('newton_iters', 'iters', '%d'), ('max_residual', 'res', '%.2e'),
    ('energy_closure_rel', 'e_close', '%.2e'), ('mass_closure_rel', 'm_close', '%.2e'),
    ('T0_K', 'T0', '%.4f'), ('P0_kPa', 'P0', '%.4f'), ('T2_K', 'T2', '%.4f'), ('P2_kPa', 'P2', '%.4f'),
    ('Nc_gg_frac', 'N', '%.6f'), ('NGG_rpm', 'NGG', '%.3f'), ('NPT_rpm', 'NPT', '%.3f'),
    ('beta', 'beta', '%.5f'), ('vsv_deg_closed', 'vsv', '%.4f'), ('bleed_frac_of_W2', 'bleed', '%.6f'),
    ('W2_kgs', 'W2', '%.5f'), ('W2c_kgs', 'W2c', '%.5f'), ('PR_c', 'PR', '%.5f'), ('eta_c_is', 'eta_c', '%.5f'),
    ('eta_c_poly', 'eta_cp', '%.5f'), ('PR_surge_same_speed', 'PRsurge', '%.4f'), ('surge_margin_pct', 'SM', '%.3f'),
    ('T25_K', 'T25', '%.3f'), ('P25_kPa', 'P25', '%.3f'), ('W_bleed_kgs', 'Wbleed', '%.5f'),
    ('T3_K', 'T3', '%.4f'), ('P3_kPa', 'P3', '%.4f'), ('W3_kgs', 'W3', '%.5f'),
    ('W_cool_kgs', 'Wcool', '%.5f'), ('W_leak_kgs', 'Wleak', '%.5f'), ('W_comb_air_kgs', 'Wcc', '%.5f'),
    ('eta_comb', 'eta_b', '%.6f'), ('FAR_comb', 'far', '%.6f'), ('WF_kgs', 'WF', '%.6f'),
    ('T4_K', 'T4', '%.3f'), ('P4_kPa', 'P4', '%.4f'), ('T41_SOT_K', 'T41', '%.3f'), ('W41_kgs', 'W41', '%.5f'),
    ('PR_hpt', 'PRh', '%.5f'), ('eta_hpt', 'eta_h', '%.5f'), ('nu_hpt_rel', 'nu_h', '%.5f'),
    ('FC41_kgsK05_kPa', 'FC41', '%.6f'), ('T48_K', 'T48', '%.3f'), ('P48_kPa', 'P48', '%.4f'),
    ('W48_kgs', 'W48', '%.5f'), ('T54_K', 'T54', '%.3f'), ('P54_kPa', 'P54', '%.4f'),
    ('PR_pt', 'PRp', '%.5f'), ('eta_pt', 'eta_p', '%.5f'), ('nu_pt_rel', 'nu_p', '%.5f'),
    ('FC54_kgsK05_kPa', 'FC54', '%.6f'), ('T5_K', 'T5', '%.3f'), ('P5_kPa', 'P5', '%.4f'), ('W5_kgs', 'W5', '%.5f'),
    ('P_comp_kW', 'Pcomp', '%.3f', 1e-3), ('P_hpt_kW', 'Phpt', '%.3f', 1e-3), ('P_pt_kW', 'Ppt', '%.3f', 1e-3),
    ('loss_gg_kW', 'loss_gg', '%.3f', 1e-3), ('loss_pt_kW', 'loss_pt', '%.3f', 1e-3),
    ('SHP_kW', 'SHP', '%.3f', 1e-3), ('heat_rate_kJ_kWh', 'HR', '%.2f'), ('eta_thermal', 'eta_th', '%.5f'),
]


def grid_levels():
    """20 degradation levels (D in percent, positive = degraded)."""
    L = []
    for g in (1.0, 2.0, 3.0, 4.0, 5.0):                       # compressor fouling
        L.append(('comp_fouling', [g, 0.4 * g, 0, 0, 0, 0]))
    for g, e in ((-1.0, 0.8), (-2.0, 1.6), (-3.0, 2.5)):       # HPT erosion
        L.append(('hpt_erosion', [0, 0, g, e, 0, 0]))
    for g, e in ((1.5, 1.0), (3.0, 2.0)):                      # HPT fouling
        L.append(('hpt_fouling', [0, 0, g, e, 0, 0]))
    L.append(('pt_fouling', [0, 0, 0, 0, 2.0, 1.0]))
    L.append(('pt_erosion', [0, 0, 0, 0, -2.0, 1.5]))
    L.append(('comp_eff_only', [0, 2.0, 0, 0, 0, 0]))
    L.append(('hpt_eff_only', [0, 0, 0, 2.0, 0, 0]))
    rng = random.Random(20240603)
    for k in range(6):                                         # random mixes within +-4
        L.append(('random_mix', [round(rng.uniform(-4.0, 4.0), 2) for _ in range(6)]))
    return L


def stratified_days(rng, n):
    """n ambient days: temperatures stratified over -5..35 C then shuffled; pressure 99..103 kPa."""
    w = 40.0 / n
    temps = [round(-5.0 + w * (i + rng.random()), 1) for i in range(n)]
    rng.shuffle(temps)
    return [(t, round(rng.uniform(99.0, 103.0), 2)) for t in temps]


def timestamp(day_index, minute):
    # nominal historian time: days after 2024-01-01 00:00 (simple calendar arithmetic)
    import datetime
    t = datetime.datetime(2024, 1, 1) + datetime.timedelta(days=day_index, minutes=minute)
    return t.strftime('%Y-%m-%d %H:%M:%S')


def fmt_measured(st, noisy, rng):
    out = []
    for name, key, conv, sig, kind, nd in TAGS:
        v = conv(st[key])
        if noisy:
            s = sig if kind == 'abs' else sig * abs(v)
            v = v + rng.gauss(0.0, s)
            out.append(('%.' + str(nd) + 'f') % round(v, nd))
        else:
            out.append('%.6f' % v)
    return out


# =============================================================================
# 9. CHECKS
# =============================================================================
def run_checks(rows_base, rows_grid, lines):
    P = lines.append
    P('=' * 78)
    P('1. Gas-property spot checks (dry air, NASA polynomials)')
    for T in (250.0, 300.0, 600.0, 1000.0, 1500.0):
        cp = AIR.cp(T)
        P('   air  T=%7.1f K  cp=%8.2f J/kgK  gamma=%.4f' % (T, cp, cp / (cp - AIR.R)))
    g = gas_f(0.025)
    P('   products FAR=0.025: cp(1500 K)=%.1f J/kgK, R=%.2f J/kgK; air R=%.2f, M_air=%.4f g/mol'
      % (g.cp(1500.0), g.R, AIR.R, M_AIR * 1e3))
    P('   h continuity at 1000 K (air): %.3e J/kg' % (AIR.h(1000.0 - 1e-9) - AIR.h(1000.0 + 1e-9)))
    P('   C12H23: M=%.3f g/mol, stoichiometric FAR=%.5f, LHV used %.1f MJ/kg'
      % (M_FUEL * 1e3, FAR_STOICH, LHV / 1e6))
    P('')
    P('1b. Compressor characteristic as scheduled (VSV + bleed on corrected speed), ISO-corrected')
    P('    %5s %5s %6s | %s' % ('Nc', 'VSV', 'bleed', '  beta: W2c kg/s / PR / eta_is  for beta = 0, 0.25, 0.5, 0.75, 1'))
    for Nc in (0.75, 0.80, 0.85, 0.90, 0.95, 1.00, 1.05):
        cells = []
        for bt in (0.0, 0.25, 0.5, 0.75, 1.0):
            w, prm1, eta, th, b, prs = comp_map(Nc, bt)
            cells.append('%5.1f/%5.2f/%.3f' % (DES['sW'] * w, 1 + DES['sPR'] * prm1, DES['sE'] * eta))
        P('    %5.2f %5.1f %6.3f | %s' % (Nc, th, b, '  '.join(cells)))
    P('')
    P('2. Design-point reproduction by the off-design solver (ISO, 25 MW, 3600 rpm)')
    sol = newton(lambda xx: cycle(xx, ISO_T0, ISO_P0, NPT_D, (0,) * 6, 'SHP', SHP_D), [0.98, 0.45, 0.97, 0.97, 0.97])
    r, st = cycle(sol[0], ISO_T0, ISO_P0, NPT_D, (0,) * 6, 'SHP', SHP_D, full=True)
    P('   from perturbed start: converged in %d iterations; x = %s' % (sol[1], ', '.join('%.8f' % v for v in sol[0])))
    P('   expected x = 1, 0.5, 1, 1, 1 -> max |x - x_d| = %.2e   %s'
      % (max(abs(a - b) for a, b in zip(sol[0], [1, BETA_D, 1, 1, 1])),
         'PASS' if max(abs(a - b) for a, b in zip(sol[0], [1, BETA_D, 1, 1, 1])) < 1e-6 else 'FAIL'))
    P('   W2=%.4f kg/s  PR=%.4f  SHP=%.3f kW  energy closure=%.2e  mass closure=%.2e'
      % (st['W2'], st['PR'], st['SHP'] / 1e3, st['e_close'], st['m_close']))
    P('')
    P('3. Closure / convergence over all written points')
    allr = rows_base + rows_grid
    P('   points: %d (baseline %d, grid %d), all converged: %s' % (len(allr), len(rows_base), len(rows_grid),
      'YES' if all(s['res'] < 1e-9 for s in allr) else 'NO'))
    P('   max residual %.2e, max |energy closure| %.2e (fraction of fuel LHV power), max |mass closure| %.2e'
      % (max(s['res'] for s in allr), max(abs(s['e_close']) for s in allr), max(abs(s['m_close']) for s in allr)))
    P('   Newton iterations: max %d, mean %.1f' % (max(s['iters'] for s in allr),
                                                    sum(s['iters'] for s in allr) / len(allr)))
    lim = [s for s in allr if s['limiter'] != 'none']
    P('   points on a control limit: %d  %s' % (len(lim), ', '.join(
        '%s/lever %.1f/%.1fC:%s %.0f of %.0f kW' % (s['group'], s['lever'], s['T0'] - 273.15, s['limiter'],
                                                   s['SHP'] / 1e3, s['demand_kW']) for s in lim)))
    P('   beta range %.3f..%.3f (map 0 = choke end, 1 = surge line); min surge margin %.1f %%'
      % (min(s['beta'] for s in allr), max(s['beta'] for s in allr), min(s['SM'] for s in allr)))
    P('   VSV closure range %.1f..%.1f deg, bleed range %.4f..%.4f of W2'
      % (min(s['vsv'] for s in allr), max(s['vsv'] for s in allr),
         min(s['bleed'] for s in allr), max(s['bleed'] for s in allr)))
    P('')
    P('4. Robustness sweep (healthy and degraded), ambient -5..+40 C, 99/103 kPa, 30..100 % lever power')
    nok = nfail = 0
    worst = []
    rng = random.Random(7)
    hdr = '   %6s %7s %6s %6s %9s %8s %7s %7s %6s %5s %6s %s' % (
        'T0_C', 'P0_kPa', 'Pdem', 'Nc', 'SHP_kW', 'T54_C', 'beta', 'SM%', 'VSV', 'bleed', 'iters', 'limiter')
    P(hdr)
    for T0c in (-5.0, 5.0, 15.0, 25.0, 35.0, 40.0):
        for i, pf in enumerate((0.30, 0.40, 0.50, 0.60, 0.70, 0.80, 0.90, 1.00)):
            P0 = 99.0 if i % 2 else 103.0
            lev = lever_for_power(pf) if pf < 1.0 else 100.0
            npt = combinator(lev)[0] * NPT_D
            for degv in ((0.0,) * 6, tuple(round(rng.uniform(-4, 4), 2) for _ in range(6))):
                try:
                    x, st = solve_point(T0c + 273.15, P0, npt, pf * SHP_D, degv)
                    nok += 1
                    if degv[0] == 0.0 and degv[1] == 0.0:
                        P('   %6.1f %7.2f %6.2f %6.4f %9.1f %8.1f %7.3f %7.2f %6.2f %5.3f %6d %s' % (
                            T0c, P0, pf, st['N'], st['SHP'] / 1e3, st['T54'] - 273.15, st['beta'], st['SM'],
                            st['vsv'], st['bleed'], st['iters'], st['limiter']))
                    if abs(st['e_close']) > 1e-9:
                        worst.append(('closure', T0c, pf, st['e_close']))
                except RuntimeError as e:
                    nfail += 1
                    worst.append(('FAIL', T0c, pf, degv, str(e)))
    P('   sweep: %d converged, %d failed %s' % (nok, nfail, 'PASS' if nfail == 0 else 'FAIL'))
    for w in worst:
        P('   !! %s' % (w,))
    # cold start: plain Newton from the ISO design point, no guess table, no continuation
    ncs = nct = 0
    for T0c in (-5.0, 15.0, 40.0):
        for pf in (0.30, 0.50, 0.70, 0.90):
            npt = combinator(lever_for_power(pf))[0] * NPT_D
            nct += 1
            sol = newton(lambda xx: cycle(xx, T0c + 273.15, 101.325, npt, (0,) * 6, 'SHP', pf * SHP_D),
                         [1.0, BETA_D, 1.0, 1.0, 1.0])
            ncs += sol is not None
    P('   cold start (plain Newton from the ISO design vector, -5/15/40 C x 30..90 %%): %d/%d converged'
      % (ncs, nct))
    P('')
    P('5. Trends along the ISO combinator line (healthy, 15 C, 101.325 kPa)')
    prev = None
    mono = {k: True for k in ('WF', 'P3', 'T3', 'T54', 'T5', 'NGG', 'P54', 'W2', 'T41')}
    P('   %6s %8s %7s %8s %8s %7s %7s %7s %7s %8s %6s %5s %6s %6s' % (
        'lever', 'SHP_kW', 'NPT', 'NGG', 'WF_kgh', 'P3kPa', 'T3_C', 'T54_C', 'T8_C', 'HR', 'Nc', 'VSV',
        'bleed', 'SM%'))
    for lev in LEVERS:
        n, p, pf = combinator(lev)
        x, st = solve_point(ISO_T0, ISO_P0, n * NPT_D, pf * SHP_D, (0,) * 6)
        P('   %6.1f %8.1f %7.1f %8.1f %8.1f %7.1f %7.1f %7.1f %7.1f %8.1f %6.4f %5.1f %6.4f %6.1f' % (
            lev, st['SHP'] / 1e3, st['NPT'], st['NGG'], st['WF'] * 3600, st['P3'], st['T3'] - 273.15,
            st['T54'] - 273.15, st['T5'] - 273.15, st['HR'], st['N'], st['vsv'], st['bleed'], st['SM']))
        if prev:
            for k in mono:
                if st[k] <= prev[k]:
                    mono[k] = False
        prev = st
    P('   monotonic increase with lever: ' + ', '.join('%s %s' % (k, 'PASS' if v else 'no') for k, v in mono.items()))
    P('')
    P('6. Health-parameter signatures at fixed power (ISO day, lever for ~74 % power): change per +1 %')
    lev = LEVERS[5]
    n, p, pf = combinator(lev)
    x0, s0 = solve_point(ISO_T0, ISO_P0, n * NPT_D, pf * SHP_D, (0,) * 6)
    names = [t[0] for t in TAGS if t[0] not in ('T_AMB_C', 'P_AMB_KPA', 'T2_C', 'NPT_RPM', 'SHP_KW')]
    P('   %-6s' % 'D' + ''.join('%11s' % nm for nm in names))
    expect = {0: ('WF_KGH', +1), 1: ('WF_KGH', +1), 3: ('WF_KGH', +1), 5: ('WF_KGH', +1)}
    expect_t = {0: ('T54_C', +1), 1: ('T54_C', +1), 3: ('T54_C', +1), 5: ('T54_C', +1)}
    for k in range(6):
        d = [0.0] * 6
        d[k] = 1.0
        x1, s1 = solve_point(ISO_T0, ISO_P0, n * NPT_D, pf * SHP_D, tuple(d), x0=x0)
        vals = []
        res = {}
        for name, key, conv, sig, kind, nd in TAGS:
            if name in names:
                dv = conv(s1[key]) - conv(s0[key])
                if kind == 'rel':
                    dv = dv / conv(s0[key]) * 100.0
                res[name] = dv
                vals.append(('%+10.3f%%' if kind == 'rel' else '%+10.3fK') % dv
                            if 'RPM' not in name and 'KPA' not in name and 'KGH' not in name
                            else '%+10.3f%%' % dv)
        tag = ''
        if k in expect:
            ok = res[expect[k][0]] > 0 and res[expect_t[k][0]] > 0
            tag = '  fuel & T54 up: %s' % ('PASS' if ok else 'FAIL')
        P('   %-6s' % DNAMES[k] + ''.join('%11s' % v for v in vals) + tag)
    P('   (pressures, speeds, fuel in % of reading; temperatures in K)')
    P('   combined patterns (same point):')
    for label, d in (('comp fouling D_GC=2, D_EC=0.8', (2.0, 0.8, 0, 0, 0, 0)),
                     ('HPT erosion  D_GT=-2, D_ET=1.6', (0, 0, -2.0, 1.6, 0, 0)),
                     ('HPT fouling  D_GT=+2, D_ET=1.3', (0, 0, 2.0, 1.3, 0, 0)),
                     ('PT fouling   D_GP=+2, D_EP=1.0', (0, 0, 0, 0, 2.0, 1.0))):
        x1, s1 = solve_point(ISO_T0, ISO_P0, n * NPT_D, pf * SHP_D, d, x0=x0)
        P('   %-32s WF %+6.2f %%  T54 %+6.1f K  T8 %+6.1f K  T3 %+5.1f K  P3 %+6.2f %%  NGG %+6.2f %%  SM %+5.1f pts'
          % (label, (s1['WF'] / s0['WF'] - 1) * 100, s1['T54'] - s0['T54'], s1['T5'] - s0['T5'],
             s1['T3'] - s0['T3'], (s1['P3'] / s0['P3'] - 1) * 100, (s1['NGG'] / s0['NGG'] - 1) * 100,
             s1['SM'] - s0['SM']))
    P('')


# =============================================================================
# 10. OUTPUT
# =============================================================================
def write_csv(path, header, rows):
    with open(path, 'w') as fh:
        fh.write(','.join(header) + '\n')
        for r in rows:
            fh.write(','.join(r) + '\n')


def main():
    size_design()
    build_iso_line()
    zero = (0.0,) * 6
    # ---------------------------------------------------------------- baseline
    rows_base = []
    for i, lev in enumerate(LEVERS):
        n, p, pf = combinator(lev)
        T0c, P0 = BASE_DAYS[i]
        x, st = solve_point(T0c + 273.15, P0, n * NPT_D, pf * SHP_D, zero)
        st.update(group='baseline', point=i, lever=lev, demand_kW=pf * SHP_D / 1e3, deg=zero,
                  ts=timestamp(3 * i, 600 + 7 * i), x=x)
        rows_base.append(st)
    # ---------------------------------------------------------------- grid
    rows_grid = []
    levels = grid_levels()
    rng_days = random.Random(4242)
    for k, (kind, d) in enumerate(levels):
        days = stratified_days(rng_days, len(LEVERS))
        for i, lev in enumerate(LEVERS):
            n, p, pf = combinator(lev)
            T0c, P0 = days[i]
            T0 = T0c + 273.15
            # healthy engine on the same day first, then march the health parameters
            xh, sh = solve_point(T0, P0, n * NPT_D, pf * SHP_D, zero)
            x, st = solve_point(T0, P0, n * NPT_D, pf * SHP_D, tuple(float(v) for v in d), x0=xh,
                                x_from=xh, par_from=(T0, P0, n * NPT_D, pf * SHP_D, zero)) \
                if sh['limiter'] == 'none' else \
                solve_point(T0, P0, n * NPT_D, pf * SHP_D, tuple(float(v) for v in d), x0=xh)
            st.update(group='level%02d' % k, kind=kind, point=i, lever=lev, demand_kW=pf * SHP_D / 1e3,
                      deg=tuple(d), ts=timestamp(40 + 12 * k + i, 480 + 11 * i + 3 * k), x=x)
            rows_grid.append(st)
    # ---------------------------------------------------------------- write
    head_meas = ['group', 'point', 'TIMESTAMP', 'LEVER_PCT'] + [t[0] for t in TAGS] + ['true_' + d for d in DNAMES]
    rng_noise = random.Random(19730815)
    for name, rows in (('baseline', rows_base), ('grid', rows_grid)):
        ex, no, it = [], [], []
        for st in rows:
            pre = [st['group'], str(st['point']), st['ts'], '%.1f' % st['lever']]
            dd = ['%.2f' % v for v in st['deg']]
            ex.append(pre + fmt_measured(st, False, None) + dd)
            no.append(pre + fmt_measured(st, True, rng_noise) + dd)
            rowi = [st['group'], str(st['point']), st['ts']]
            for spec in INTERNAL:
                col, key, f = spec[0], spec[1], spec[2]
                v = st[key]
                if len(spec) > 3:
                    v = v * spec[3]
                rowi.append(f % v)
            it.append(rowi + dd)
        write_csv(os.path.join(OUT, name + '_exact.csv'), head_meas, ex)
        write_csv(os.path.join(OUT, name + '_noisy.csv'), head_meas, no)
        write_csv(os.path.join(OUT, name + '_internal.csv'),
                  ['group', 'point', 'TIMESTAMP'] + [s[0] for s in INTERNAL] + ['true_' + d for d in DNAMES], it)
    write_design()
    # ---------------------------------------------------------------- checks
    lines = ['indep3 self-checks (generated by sim.py)', '']
    run_checks(rows_base, rows_grid, lines)
    lines.append('7. Grid levels')
    for k, (kind, d) in enumerate(levels):
        rr = [s for s in rows_grid if s['group'] == 'level%02d' % k]
        lines.append('   level%02d %-14s D=%s  converged %d/%d  limited %d' % (
            k, kind, ' '.join('%+5.2f' % v for v in d), sum(1 for s in rr if s['res'] < 1e-9), len(rr),
            sum(1 for s in rr if s['limiter'] != 'none')))
    lines.append('')
    lines.append('cycle evaluations: %d (wall time is printed on stdout only, to keep this file deterministic)'
                 % STATS['cycles'])
    with open(os.path.join(OUT, 'checks.txt'), 'w') as fh:
        fh.write('\n'.join(lines) + '\n')
    print('\n'.join(lines))
    print('wall time %.2f s' % (time.time() - T_START))


def write_design():
    """Vendor-style datasheet: what the plant engineer has, no internal map equations."""
    x = [1.0, BETA_D, 1.0, 1.0, 1.0]
    r, st = cycle(x, ISO_T0, ISO_P0, NPT_D, (0,) * 6, 'SHP', SHP_D, full=True)
    L = []
    P = L.append
    P('MGT-25 MARINE GAS TURBINE -- PERFORMANCE DATASHEET (new & clean engine)')
    P('Two-shaft aero-derivative: 16-stage axial GG compressor with VSVs (IGV + stators 1-6) and')
    P('stage-8 handling-bleed valve, annular combustor, 2-stage air-cooled HP turbine,')
    P('6-stage free power turbine, output via torque-meter shaft to reduction gear and CPP.')
    P('')
    P('ISO RATING  (15 C, 101.325 kPa, dry air; inlet loss %.2f kPa, exhaust loss %.2f kPa;'
      % (st['P0'] - st['P2'], st['P5'] - st['P0']))
    P('             marine gas oil; power at the PT output-shaft torque meter)')
    P('  Shaft power (torque meter)         %9.0f kW' % (st['SHP'] / 1e3))
    P('  Heat rate (LHV)                    %9.0f kJ/kWh' % st['HR'])
    P('  Thermal efficiency (LHV)           %9.1f %%' % (st['eta_th'] * 100))
    P('  Fuel flow                          %9.0f kg/h' % (st['WF'] * 3600))
    P('  Compressor inlet mass flow         %9.1f kg/s' % st['W2'])
    P('  Compressor pressure ratio P3/P2    %9.1f' % st['PR'])
    P('  Compressor discharge P3 / T3       %9.0f kPa a / %.0f C' % (st['P3'], st['T3'] - 273.15))
    P('  Combustor exit temperature T4      %9.0f C  (%.0f K)' % (st['T4'] - 273.15, st['T4']))
    P('  HPT rotor inlet temperature (SOT)  %9.0f C  (%.0f K)' % (st['T41'] - 273.15, st['T41']))
    P('  PT inlet T54 / P54                 %9.0f C / %.0f kPa a' % (st['T54'] - 273.15, st['P54']))
    P('  Exhaust gas flow                   %9.1f kg/s' % st['W5'])
    P('  Exhaust gas temperature (T8)       %9.0f C' % (st['T5'] - 273.15))
    P('  GG speed NGG                       %9.0f rpm (100 %%)' % st['NGG'])
    P('  PT speed NPT                       %9.0f rpm (100 %%)' % st['NPT'])
    P('')
    P('COMPONENT DATA AT ISO RATING')
    P('  Compressor isentropic / polytropic efficiency   %.3f / %.3f' % (st['eta_c'], st['eta_cp']))
    P('  Compressor surge margin at rating (const. speed) %.0f %%' % st['SM'])
    P('  HP turbine isentropic efficiency (2 stages)     %.3f' % st['eta_h'])
    P('  HP turbine pressure ratio                        %.2f' % st['PRh'])
    P('  Power turbine isentropic efficiency              %.3f' % st['eta_p'])
    P('  Power turbine pressure ratio                     %.2f' % st['PRp'])
    P('  Combustion efficiency                            %.4f' % st['eta_b'])
    P('  Mechanical: GG %.1f %% of HPT power + accessories %.0f kW; PT bearings %.1f %% + %.0f kW'
      % (MECH_GG * 100, P_ACC_D / 1e3, MECH_PT * 100, P_PTLOSS_D / 1e3))
    P('  Cooling/secondary air (% of compressor delivery, all from compressor discharge):')
    P('     HPT stage-1 nozzle %.1f %%, stage-1 rotor %.1f %%, stage-2 nozzle+rotor %.1f %%, '
      'CDP seal leakage overboard %.1f %%' % (COOL_NGV1 * 100, COOL_ROT1 * 100, COOL_ST2 * 100, LEAK * 100))
    P('  Pressure losses at rating: inlet %.1f %%, combustor %.1f %% of P3, inter-turbine duct %.1f %%,'
      % (K_IN / (1 + K_IN) * 100, K_CC * 100, K_ITD * 100))
    P('     exhaust system back-pressure %.1f %% of ambient' % (K_EX * 100))
    P('')
    P('VARIABLE STATOR VANES (IGV + stator rows 1-6), scheduled on corrected GG speed')
    P('  NGG corrected = NGG * sqrt(288.15 K / T2)')
    P('  %10s %10s %12s' % ('NGGcorr %', 'NGGcorr rpm', 'VSV closed deg'))
    for nc in (1.00, 0.95, 0.925, 0.90, 0.875, 0.85, 0.825, 0.80, 0.775, 0.75, 0.70):
        P('  %10.1f %10.0f %12.1f' % (nc * 100, nc * NGG_D, vsv_angle(nc)))
    P('  (0 deg = full-open stop; vanes close progressively below 95 % corrected speed)')
    P('')
    P('HANDLING BLEED VALVE (stage 8, dumped overboard), scheduled on corrected GG speed')
    P('  %10s %12s' % ('NGGcorr %', 'bleed % W2'))
    for nc in (0.70, 0.76, 0.79, 0.82, 0.85, 0.88, 0.90):
        P('  %10.1f %12.2f' % (nc * 100, bleed_frac(nc) * 100))
    P('  (valve position is not logged)')
    P('')
    P('CONTROL LIMITS')
    P('  T54 max continuous       %.0f C' % (DES['T54_MAX'] - 273.15))
    P('  NGG max (physical)       %.0f rpm' % NGG_MAX)
    P('  NGG corrected max        %.1f %%' % (NC_MAX * 100))
    P('  At the limit the load controller reduces pitch: power falls short of the lever demand.')
    P('')
    P('COMBINATOR SCHEDULE (bridge lever -> PT speed and propeller pitch; power absorbed at trial')
    P('condition, identical for all ambient conditions)')
    P('  %6s %10s %10s %10s %10s' % ('lever%', 'NPT %', 'NPT rpm', 'pitch %', 'SHP kW'))
    for lev in COMB_LEVER:
        n, p, pf = combinator(lev)
        P('  %6.0f %10.1f %10.0f %10.1f %10.0f' % (lev, n * 100, n * NPT_D, p * 100, pf * SHP_D / 1e3))
    P('  Linear interpolation of NPT and pitch in lever; absorbed power follows the propeller')
    P('  law P = P_rated * n^3 * (%.2f + %.2f * pitch^1.5).' % (PROP_Q0, 1 - PROP_Q0))
    P('')
    P('FUEL')
    P('  Marine gas oil (DMA/F-76 type), modelled as C%dH%d, M = %.1f g/mol, H mass fraction %.1f %%'
      % (FUEL_C, FUEL_H, M_FUEL * 1e3, FUEL_H * 1.00794e-3 / M_FUEL * 100))
    P('  LHV = %.1f MJ/kg, supplied at %.0f C, stoichiometric fuel/air ratio %.4f'
      % (LHV / 1e6, T_FUEL - 273.15, FAR_STOICH))
    P('')
    P('TYPICAL ISO PART-LOAD PERFORMANCE ON THE COMBINATOR (new & clean)')
    P('  %6s %8s %7s %8s %8s %8s %7s %7s' % ('lever%', 'SHP kW', 'NPT', 'NGG', 'WF kg/h', 'HR', 'T54 C', 'T8 C'))
    for lev in (40, 50, 60, 70, 80, 90, 100):
        n, p, pf = combinator(lev)
        x, s2 = solve_point(ISO_T0, ISO_P0, n * NPT_D, pf * SHP_D, (0,) * 6)
        P('  %6.0f %8.0f %7.0f %8.0f %8.0f %8.0f %7.0f %7.0f' % (
            lev, s2['SHP'] / 1e3, s2['NPT'], s2['NGG'], s2['WF'] * 3600, s2['HR'], s2['T54'] - 273.15,
            s2['T5'] - 273.15))
    with open(os.path.join(OUT, 'design.txt'), 'w') as fh:
        fh.write('\n'.join(L) + '\n')


if __name__ == '__main__':
    main()
