#!/usr/bin/env python3
"""
indep2 -- independent steady-state performance model of a ~13 MW two-shaft
industrial gas turbine (gas generator + free power turbine) driving a 60 Hz
generator through a gearbox.  Python 3 standard library only.

Written from textbook component-matching physics (Saravanamuttoo/Rogers/Cohen,
Walsh & Fletcher, Kurzke).  Everything (maps, losses, schedules, numbers) is
chosen here; see README.md.  `python3 sim.py` regenerates every file of this
folder except README.md.

Station numbering (SAE ARP 755 style):
  0 ambient, 1 compressor face (after inlet filter/duct), 3 compressor exit,
  31 combustor air inlet, 4 combustor exit (TIT), 41 HPT rotor inlet (after
  NGV cooling air mixed in), 42 HPT rotor exit, 45 HPT exit after rotor
  cooling air mixed in, 48 PT inlet (after inter-turbine duct), 5 PT exit,
  then exhaust diffuser/stack to ambient.
"""
import math
import os
import random
import sys
import time
from datetime import datetime, timedelta, timezone

OUT = os.path.dirname(os.path.abspath(__file__))

# =============================================================================
# Units
# =============================================================================
PA_PER_PSI = 6894.757293168
KG_PER_LB = 0.45359237
KJ_PER_BTU = 1.05505585262


def k2f(t):
    return t * 1.8 - 459.67


def k2c(t):
    return t - 273.15


def pa2psi(p):
    return p / PA_PER_PSI


def kgs2lbh(w):
    return w * 3600.0 / KG_PER_LB


# =============================================================================
# Thermodynamic properties: ideal-gas mixtures, NASA 7-coefficient polynomials
# (GRI-Mech 3.0 thermodynamic data base, Smith et al. 1999, as distributed in
# Cantera's gri30.yaml).  Two ranges, common break at 1000 K.  Enthalpies are
# absolute (include the enthalpy of formation), so combustion, mixing and the
# fuel heating value all follow from one consistent set of data.
# =============================================================================
R_U = 8.314462618  # J/(mol K)
ATW = {'C': 12.011, 'H': 1.008, 'O': 15.999, 'N': 14.007, 'Ar': 39.948}
SPECIES = ['N2', 'O2', 'AR', 'CO2', 'H2O', 'CH4', 'C2H6', 'C3H8']
ATOMS = {'N2': {'N': 2}, 'O2': {'O': 2}, 'AR': {'Ar': 1}, 'CO2': {'C': 1, 'O': 2},
         'H2O': {'H': 2, 'O': 1}, 'CH4': {'C': 1, 'H': 4}, 'C2H6': {'C': 2, 'H': 6},
         'C3H8': {'C': 3, 'H': 8}}
MOLM = {s: sum(ATW[a] * n for a, n in ATOMS[s].items()) * 1e-3 for s in SPECIES}  # kg/mol
NASA = {
    'N2': ([3.298677, 1.4082404e-03, -3.963222e-06, 5.641515e-09, -2.444854e-12, -1020.8999, 3.950372],
           [2.92664, 1.4879768e-03, -5.68476e-07, 1.0097038e-10, -6.753351e-15, -922.7977, 5.980528]),
    'O2': ([3.78245636, -2.99673416e-03, 9.84730201e-06, -9.68129509e-09, 3.24372837e-12, -1063.94356, 3.65767573],
           [3.28253784, 1.48308754e-03, -7.57966669e-07, 2.09470555e-10, -2.16717794e-14, -1088.45772, 5.45323129]),
    'AR': ([2.5, 0.0, 0.0, 0.0, 0.0, -745.375, 4.366],
           [2.5, 0.0, 0.0, 0.0, 0.0, -745.375, 4.366]),
    'CO2': ([2.35677352, 8.98459677e-03, -7.12356269e-06, 2.45919022e-09, -1.43699548e-13, -4.83719697e+04, 9.90105222],
            [3.85746029, 4.41437026e-03, -2.21481404e-06, 5.23490188e-10, -4.72084164e-14, -4.8759166e+04, 2.27163806]),
    'H2O': ([4.19864056, -2.0364341e-03, 6.52040211e-06, -5.48797062e-09, 1.77197817e-12, -3.02937267e+04, -0.849032208],
            [3.03399249, 2.17691804e-03, -1.64072518e-07, -9.7041987e-11, 1.68200992e-14, -3.00042971e+04, 4.9667701]),
    'CH4': ([5.14987613, -0.0136709788, 4.91800599e-05, -4.84743026e-08, 1.66693956e-11, -1.02466476e+04, -4.64130376],
            [0.074851495, 0.0133909467, -5.73285809e-06, 1.22292535e-09, -1.0181523e-13, -9468.34459, 18.437318]),
    'C2H6': ([4.29142492, -5.5015427e-03, 5.99438288e-05, -7.08466285e-08, 2.68685771e-11, -1.15222055e+04, 2.66682316],
             [1.0718815, 0.0216852677, -1.00256067e-05, 2.21412001e-09, -1.9000289e-13, -1.14263932e+04, 15.1156107]),
    'C3H8': ([0.93355381, 0.026424579, 6.1059727e-06, -2.1977499e-08, 9.5149253e-12, -1.395852e+04, 19.201691],
             [7.5341368, 0.018872239, -6.2718491e-06, 9.1475649e-10, -4.7838069e-14, -1.6467516e+04, -17.892349]),
}
T_BREAK = 1000.0
T_REF = 298.15


class Mix:
    """Ideal-gas mixture of fixed composition (mole fractions over SPECIES)."""

    def __init__(self, x):
        tot = sum(x)
        self.x = [xi / tot for xi in x]
        self.M = sum(xi * MOLM[s] for xi, s in zip(self.x, SPECIES))  # kg/mol
        self.lo = [sum(xi * NASA[s][0][k] for xi, s in zip(self.x, SPECIES)) for k in range(7)]
        self.hi = [sum(xi * NASA[s][1][k] for xi, s in zip(self.x, SPECIES)) for k in range(7)]
        self.R = R_U / self.M  # J/(kg K)

    def _a(self, T):
        return self.lo if T < T_BREAK else self.hi

    def cp(self, T):  # J/(kg K)
        a = self._a(T)
        return self.R * (a[0] + T * (a[1] + T * (a[2] + T * (a[3] + T * a[4]))))

    def h(self, T):  # J/kg, absolute (formation included)
        a = self._a(T)
        return self.R * (T * (a[0] + T * (a[1] / 2 + T * (a[2] / 3 + T * (a[3] / 4 + T * a[4] / 5)))) + a[5])

    def Hm(self, T):  # J/mol
        return self.h(T) * self.M

    def phi(self, T):  # s0/R (dimensionless, per mole)
        a = self._a(T)
        return a[0] * math.log(T) + T * (a[1] + T * (a[2] / 2 + T * (a[3] / 3 + T * a[4] / 4))) + a[6]

    def T_from_h(self, h, T0=900.0):
        T = T0
        for _ in range(60):
            dT = (self.h(T) - h) / self.cp(T)
            T -= dT
            if abs(dT) < 1e-10:
                return T
        raise RuntimeError('T_from_h did not converge')

    def T_from_phi(self, ph, T0=900.0):
        T = T0
        for _ in range(60):
            dT = (self.phi(T) - ph) * T * self.R / self.cp(T)
            T -= dT
            if abs(dT) < 1e-10:
                return T
        raise RuntimeError('T_from_phi did not converge')


def vec(d):
    return [d.get(s, 0.0) for s in SPECIES]


# Dry air (US Standard Atmosphere composition, normalised; Ne, He, ... lumped in Ar)
X_AIR = vec({'N2': 0.78084, 'O2': 0.209476, 'AR': 0.00934, 'CO2': 0.000412})
_t = sum(X_AIR)
X_AIR = [v / _t for v in X_AIR]
AIR = Mix(X_AIR)

# Pipeline natural gas, mole fractions
FUEL_X = {'CH4': 0.92, 'C2H6': 0.04, 'C3H8': 0.01, 'N2': 0.02, 'CO2': 0.01}
FUEL = Mix(vec(FUEL_X))
T_FUEL = 298.15  # fuel delivered to the burners at 25 degC
# complete-combustion product change per mole of fuel (O2 consumed negative)
_C = sum(FUEL_X.get(s, 0) * ATOMS[s].get('C', 0) for s in ['CH4', 'C2H6', 'C3H8'])
_H = sum(FUEL_X.get(s, 0) * ATOMS[s].get('H', 0) for s in ['CH4', 'C2H6', 'C3H8'])
P_F = vec({'CO2': _C + FUEL_X['CO2'], 'H2O': _H / 2.0, 'N2': FUEL_X['N2'], 'O2': -(_C + _H / 4.0)})


def Pf_H(T):
    """Sum over product-change vector of molar enthalpies (J per mol fuel)."""
    tot = 0.0
    for n, s in zip(P_F, SPECIES):
        if n != 0.0:
            a = NASA[s][0] if T < T_BREAK else NASA[s][1]
            tot += n * R_U * (T * (a[0] + T * (a[1] / 2 + T * (a[2] / 3 + T * (a[3] / 4 + T * a[4] / 5)))) + a[5])
    return tot


LHV_MOLAR = FUEL.Hm(T_REF) - Pf_H(T_REF)  # J/mol fuel, water as vapour, 25 degC
LHV = LHV_MOLAR / FUEL.M  # J/kg
STOICH_FAR = FUEL.M / ((_C + _H / 4.0) / AIR.x[SPECIES.index('O2')] * AIR.M)


def products(n_air, n_f):
    """Mix of burnt gas from n_air mol of air and n_f mol of fuel (complete combustion)."""
    x = [n_air * xa + n_f * pf for xa, pf in zip(X_AIR, P_F)]
    return Mix(x), sum(x)


def mix_streams(streams):
    """streams: list of (W kg/s, Mix, T).  Adiabatic mixing. Returns (W, Mix, T)."""
    W = sum(s[0] for s in streams)
    nx = [0.0] * len(SPECIES)
    H = 0.0
    for Wi, m, Ti in streams:
        ni = Wi / m.M
        for k in range(len(SPECIES)):
            nx[k] += ni * m.x[k]
        H += Wi * m.h(Ti)
    mm = Mix(nx)
    T = mm.T_from_h(H / W, streams[0][2])
    return W, mm, T


# =============================================================================
# Engine definition (design point = ISO full load)
# =============================================================================
ISO_T = 288.15
ISO_P = 101325.0
D = dict(
    W1=42.0,            # kg/s compressor inlet air flow at ISO full load
    PR=16.0,            # compressor total pressure ratio
    ETA_C=0.866,        # compressor isentropic efficiency (polytropic ~0.905)
    DP_IN=1000.0,       # Pa inlet filter + duct loss at ISO full load (~4 inH2O)
    F_NGV=0.06,         # NGV cooling air, fraction of W1, from compressor exit
    F_ROT=0.04,         # HPT rotor cooling air, fraction of W1, from compressor exit
    DP_B=0.040,         # combustor total pressure loss dP/P3 at design
    ETA_B=0.995,        # combustion efficiency
    ETA_H=0.880,        # HPT isentropic efficiency (total-total, rotor stream)
    DP_ITD=0.015,       # inter-turbine duct dP/P45 at design
    ETA_P=0.905,        # PT isentropic efficiency (total-total)
    DP_EX=2000.0,       # Pa exhaust diffuser + stack back pressure at design (~8 inH2O)
    NGG=11200.0,        # rpm gas generator at ISO full load
    NPT=8500.0,         # rpm power turbine (synchronous)
    NGEN=1800.0,        # rpm 4-pole 60 Hz generator
    GG_LOSS=0.005,      # GG shaft loss as fraction of compressor power at design, ~N^2
    MW=13.0,            # ISO electrical rating at the generator terminals
    GB0=0.004, GB1=0.008,          # gearbox loss = GB0*Pref + GB1*Pout
    GEN0=0.0084853, GEN2=0.0088077,  # generator loss = Pref*(GEN0 + GEN2*(Pe/Pref)^2)
    BETA_D=0.55,        # design map position
)
PREF = D['MW'] * 1e6

# --- compressor map (own analytic form) --------------------------------------
# n = relative corrected speed N/sqrt(T1/288.15)/NGG_design, beta in [0,1]:
# beta = 0 on the surge line, beta = 1 at the choke end of each speed line.
MAP_PS_EXP = 2.3     # (PR-1) at surge ~ n^2.3
MAP_PCH = 0.45       # (PR-1) at choke end / (PR-1) at surge
VIGV_MAX = 30.0      # deg closure
VIGV_N0, VIGV_N1 = 0.92, 0.80   # fully open above N0, fully closed (VIGV_MAX) below N1
VIGV_KW, VIGV_KQ, VIGV_KE = 0.0070, 0.0085, 6.0e-5
BLEED_MAX = 0.06
BLEED_N0, BLEED_N1 = 0.75, 0.65  # closed above N0, fully open (6 %) below N1


def vigv_schedule(n):
    if n >= VIGV_N0:
        return 0.0
    if n <= VIGV_N1:
        return VIGV_MAX
    return VIGV_MAX * (VIGV_N0 - n) / (VIGV_N0 - VIGV_N1)


def bleed_schedule(n):
    if n >= BLEED_N0:
        return 0.0
    if n <= BLEED_N1:
        return BLEED_MAX
    return BLEED_MAX * (BLEED_N0 - n) / (BLEED_N0 - BLEED_N1)


def cmap_raw(n, beta, vigv):
    """Normalised map: returns (w, q, e, q_surge) with w ~ corrected flow,
    q ~ PR-1, e ~ efficiency, all relative."""
    wch = n ** (1.5 + 1.5 * (1.0 - n))
    ws = wch * (0.92 - 0.25 * (1.0 - n))
    w = ws + (wch - ws) * (1.0 - (1.0 - beta) ** 2)
    qs = n ** MAP_PS_EXP
    q = qs * (1.0 - (1.0 - MAP_PCH) * beta * beta)
    e = 1.0 - 1.4 * (n - 0.96) ** 2 - 0.35 * (beta - 0.45) ** 2
    fw = 1.0 - VIGV_KW * vigv
    fq = 1.0 - VIGV_KQ * vigv
    fe = 1.0 - VIGV_KE * vigv * vigv
    return w * fw, q * fq, e * fe, qs * fq


_W_D, _Q_D, _E_D, _QS_D = cmap_raw(1.0, D['BETA_D'], 0.0)


def cmap(n, beta, vigv):
    w, q, e, qs = cmap_raw(n, beta, vigv)
    return (w / _W_D, 1.0 + (D['PR'] - 1.0) * q / _Q_D, e / _E_D,
            1.0 + (D['PR'] - 1.0) * qs / _Q_D)


# --- turbines -----------------------------------------------------------------
HPT_M = 4.0          # HPT capacity ~ sqrt(1 - PR^-4): nearly choked
PT_M = 2.0           # PT capacity: Stodola ellipse sqrt(1 - PR^-2)
HPT_K, HPT_RD = 0.5, 0.98   # eta/eta_max = 1 - K (nu/nu_opt - 1)^2, design at nu/nu_opt = RD
PT_K, PT_RD = 0.6, 0.97


def cap_fn(pr, m):
    return math.sqrt(1.0 - pr ** (-m))


def eff_fn(r, k):
    return 1.0 - k * (r - 1.0) ** 2


# --- electrical chain ---------------------------------------------------------
def elec_from_shaft(p_pt):
    """PT shaft power (W) -> electrical power at generator terminals (W)."""
    p_go = (p_pt - D['GB0'] * PREF) / (1.0 + D['GB1'])
    a = D['GEN2'] / PREF
    c = D['GEN0'] * PREF - p_go
    return (-1.0 + math.sqrt(1.0 - 4.0 * a * c)) / (2.0 * a)


def shaft_from_elec(pe):
    p_go = pe + PREF * (D['GEN0'] + D['GEN2'] * (pe / PREF) ** 2)
    return p_go * (1.0 + D['GB1']) + D['GB0'] * PREF


# =============================================================================
# Design-point calculation (fixes all scaling constants)
# =============================================================================
S = {}  # scaling constants


def design_cycle(T4, store=False):
    T1 = ISO_T
    P1 = ISO_P - D['DP_IN']
    W1 = D['W1']
    P3 = P1 * D['PR']
    h1 = AIR.h(T1)
    T3s = AIR.T_from_phi(AIR.phi(T1) + math.log(D['PR']), 600.0)
    h3 = h1 + (AIR.h(T3s) - h1) / D['ETA_C']
    T3 = AIR.T_from_h(h3, T3s)
    Pc = W1 * (h3 - h1)
    Wngv, Wrot = D['F_NGV'] * W1, D['F_ROT'] * W1
    W31 = W1 - Wngv - Wrot
    P4 = P3 * (1.0 - D['DP_B'])
    n_air = W31 / AIR.M
    n_f = n_air * (AIR.Hm(T4) - AIR.Hm(T3)) / (FUEL.Hm(T_FUEL) - (1 - D['ETA_B']) * LHV_MOLAR - Pf_H(T4))
    Wf = n_f * FUEL.M
    m4, _ = products(n_air, n_f)
    W4 = W31 + Wf
    W41, m41, T41 = mix_streams([(W4, m4, T4), (Wngv, AIR, T3)])
    P41 = P4
    loss = D['GG_LOSS'] * Pc
    dh = (Pc + loss) / W41
    dhs = dh / D['ETA_H']
    h41 = m41.h(T41)
    T42s = m41.T_from_h(h41 - dhs, T41 * 0.75)
    PRh = math.exp(m41.phi(T41) - m41.phi(T42s))
    T42 = m41.T_from_h(h41 - dh, T42s)
    P45 = P41 / PRh
    W45, m45, T45 = mix_streams([(W41, m41, T42), (Wrot, AIR, T3)])
    P48 = P45 * (1.0 - D['DP_ITD'])
    T48 = T45
    P5 = ISO_P + D['DP_EX']
    PRp = P48 / P5
    h48 = m45.h(T48)
    T5s = m45.T_from_phi(m45.phi(T48) - math.log(PRp), T48 * 0.75)
    dhsp = h48 - m45.h(T5s)
    T5 = m45.T_from_h(h48 - D['ETA_P'] * dhsp, T5s)
    Ppt = W45 * D['ETA_P'] * dhsp
    Pe = elec_from_shaft(Ppt)
    if store:
        S.update(dict(
            WC=W1 * math.sqrt(T1 / ISO_T) / (P1 / ISO_P), Q31=W31 * math.sqrt(T3) / P3,
            Q41=W41 * math.sqrt(T41) / P41, PRH=PRh, DHSH=dhs, Q45=W45 * math.sqrt(T45) / P45,
            Q48=W45 * math.sqrt(T48) / P48, PRP=PRp, DHSP=dhsp,
            KEX=D['DP_EX'] * ISO_P / (W45 ** 2 * T5), PC=Pc, T4=T4,
            DPIN=D['DP_IN'] / ISO_P))
    return Pe


def design():
    a, b = 1400.0, 1500.0
    fa, fb = design_cycle(a) - PREF, design_cycle(b) - PREF
    for _ in range(50):
        c = b - fb * (b - a) / (fb - fa)
        a, fa = b, fb
        b, fb = c, design_cycle(c) - PREF
        if abs(fb) < 1e-6:
            break
    design_cycle(b, store=True)
    return b


# =============================================================================
# Off-design model
# =============================================================================
HEALTH_KEYS = ['D_GC', 'D_EC', 'D_GT', 'D_ET', 'D_GP', 'D_EP']


def engine(x, Tamb, Pamb, hp, mode, target, full=False):
    """x = [n (rel corrected GG speed), beta, T4 (K), PR_HPT, PR_PT].
    mode 'power': target = electrical W; mode 'tit': target = T4 (K).
    Returns residual vector (and a state dict if full)."""
    n, beta, T4, PRh, PRp = x
    dgc, dec, dgt, det, dgp, dep = [hp.get(k, 0.0) for k in HEALTH_KEYS]
    T1 = Tamb
    th = T1 / ISO_T
    vigv = vigv_schedule(n)
    bleed = bleed_schedule(n)
    wrel, PR, erel, PRsurge = cmap(n, beta, vigv)
    Wc = S['WC'] * wrel * (1.0 - dgc / 100.0)
    eta_c = D['ETA_C'] * erel * (1.0 - dec / 100.0)
    P1 = Pamb * (1.0 - S['DPIN'] * (Wc / S['WC']) ** 2)
    W1 = Wc * (P1 / ISO_P) / math.sqrt(th)
    P3 = P1 * PR
    h1 = AIR.h(T1)
    T3s = AIR.T_from_phi(AIR.phi(T1) + math.log(PR), 600.0)
    h3 = h1 + (AIR.h(T3s) - h1) / eta_c
    T3 = AIR.T_from_h(h3, T3s)
    Pc = W1 * (h3 - h1)
    N = n * D['NGG'] * math.sqrt(th)
    Wbl = bleed * W1
    Wngv, Wrot = D['F_NGV'] * W1, D['F_ROT'] * W1
    W31 = W1 - Wbl - Wngv - Wrot
    dpb = D['DP_B'] * (W31 * math.sqrt(T3) / P3 / S['Q31']) ** 2
    P4 = P3 * (1.0 - dpb)
    n_air = W31 / AIR.M
    n_f = n_air * (AIR.Hm(T4) - AIR.Hm(T3)) / (FUEL.Hm(T_FUEL) - (1 - D['ETA_B']) * LHV_MOLAR - Pf_H(T4))
    Wf = n_f * FUEL.M
    m4, _ = products(n_air, n_f)
    W4 = W31 + Wf
    W41, m41, T41 = mix_streams([(W4, m4, T4), (Wngv, AIR, T3)])
    P41 = P4
    Q41 = W41 * math.sqrt(T41) / P41
    Q41m = S['Q41'] * cap_fn(PRh, HPT_M) / cap_fn(S['PRH'], HPT_M) * (1.0 - dgt / 100.0)
    r1 = Q41 / Q41m - 1.0
    h41 = m41.h(T41)
    T42s = m41.T_from_phi(m41.phi(T41) - math.log(PRh), T41 * 0.75)
    dhs = h41 - m41.h(T42s)
    nu = (N / D['NGG']) * math.sqrt(S['DHSH'] / dhs)
    eta_h = D['ETA_H'] * eff_fn(nu * HPT_RD, HPT_K) / eff_fn(HPT_RD, HPT_K) * (1.0 - det / 100.0)
    h42 = h41 - eta_h * dhs
    T42 = m41.T_from_h(h42, T42s)
    Ph = W41 * eta_h * dhs
    P45 = P41 / PRh
    W45, m45, T45 = mix_streams([(W41, m41, T42), (Wrot, AIR, T3)])
    Ploss = D['GG_LOSS'] * S['PC'] * (N / D['NGG']) ** 2
    r2 = (Ph - Pc - Ploss) / S['PC']
    Q45 = W45 * math.sqrt(T45) / P45
    P48 = P45 * (1.0 - D['DP_ITD'] * (Q45 / S['Q45']) ** 2)
    T48 = T45
    Q48 = W45 * math.sqrt(T48) / P48
    Q48m = S['Q48'] * cap_fn(PRp, PT_M) / cap_fn(S['PRP'], PT_M) * (1.0 - dgp / 100.0)
    r3 = Q48 / Q48m - 1.0
    P5 = P48 / PRp
    h48 = m45.h(T48)
    T5s = m45.T_from_phi(m45.phi(T48) - math.log(PRp), T48 * 0.8)
    dhsp = h48 - m45.h(T5s)
    Npt = D['NPT']
    nup = (Npt / D['NPT']) * math.sqrt(S['DHSP'] / dhsp)
    eta_p = D['ETA_P'] * eff_fn(nup * PT_RD, PT_K) / eff_fn(PT_RD, PT_K) * (1.0 - dep / 100.0)
    h5 = h48 - eta_p * dhsp
    T5 = m45.T_from_h(h5, T5s)
    Ppt = W45 * eta_p * dhsp
    P5ex = Pamb + S['KEX'] * W45 ** 2 * T5 / Pamb
    r4 = (P5 - P5ex) / Pamb
    Pe = elec_from_shaft(Ppt)
    if mode == 'power':
        r5 = (Pe - target) / PREF
    else:
        r5 = (T4 - target) / 1000.0
    res = [r1, r2, r3, r4, r5]
    if not full:
        return res
    st = dict(
        Tamb=Tamb, Pamb=Pamb, T1=T1, P1=P1, Nc=n, N_gg=N, N_pt=Npt, beta=beta,
        vigv=vigv, bleed=bleed, Wc=Wc, W1=W1, PR=PR, PR_surge=PRsurge,
        SM=PRsurge / PR - 1.0, eta_c=eta_c, T3=T3, P3=P3, P_comp=Pc,
        W_bleed=Wbl, W_ngv=Wngv, W_rot=Wrot, W31=W31, dp_comb=dpb, P4=P4, T4=T4,
        W_fuel=Wf, FAR=Wf / W31, W4=W4, T41=T41, W41=W41, Q41=Q41, PR_hpt=PRh,
        eta_hpt=eta_h, nu_hpt=nu * HPT_RD, P_hpt=Ph, T42=T42, P45=P45, T45=T45, W45=W45,
        P48=P48, T48=T48, Q48=Q48, PR_pt=PRp, eta_pt=eta_p, nu_pt=nup * PT_RD,
        P5=P5, T5=T5, W5=W45, P_pt=Ppt, P_ggloss=Ploss, P_elec=Pe,
        res=res, m45=m45, m4=m4)
    p_go = (Ppt - D['GB0'] * PREF) / (1.0 + D['GB1'])
    st['eta_gb'] = p_go / Ppt
    st['eta_gen'] = Pe / p_go
    st['eta_th'] = Pe / (Wf * LHV)
    st['HR_kJkWh'] = 3600.0 / st['eta_th']
    return res, st


def lin_solve(A, b):
    n = len(b)
    M = [row[:] + [b[i]] for i, row in enumerate(A)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(M[r][c]))
        if abs(M[p][c]) < 1e-300:
            raise ZeroDivisionError
        M[c], M[p] = M[p], M[c]
        for r in range(c + 1, n):
            f = M[r][c] / M[c][c]
            if f:
                for k in range(c, n + 1):
                    M[r][k] -= f * M[c][k]
    x = [0.0] * n
    for r in range(n - 1, -1, -1):
        x[r] = (M[r][n] - sum(M[r][k] * x[k] for k in range(r + 1, n))) / M[r][r]
    return x


XMIN = [0.3, -0.5, 500.0, 1.05, 1.02]
XMAX = [1.3, 1.5, 2500.0, 20.0, 20.0]
TOL = 1e-11


def newton(x0, args, maxit=40):
    x = list(x0)
    try:
        r = engine(x, *args)
    except (ValueError, RuntimeError, ZeroDivisionError, OverflowError):
        return None, 0, float('inf')
    nr = max(abs(v) for v in r)
    for it in range(1, maxit + 1):
        if nr < TOL:
            return x, it - 1, nr
        J = [[0.0] * 5 for _ in range(5)]
        try:
            for j in range(5):
                hstep = 1e-7 * max(abs(x[j]), 1.0)
                xp = list(x)
                xp[j] += hstep
                rp = engine(xp, *args)
                for i in range(5):
                    J[i][j] = (rp[i] - r[i]) / hstep
            dx = lin_solve(J, [-v for v in r])
        except (ValueError, RuntimeError, ZeroDivisionError, OverflowError):
            return None, it, nr
        lam = 1.0
        ok = False
        for _ in range(25):
            xn = [min(max(xi + lam * di, lo), hi) for xi, di, lo, hi in zip(x, dx, XMIN, XMAX)]
            try:
                rn = engine(xn, *args)
                nrn = max(abs(v) for v in rn)
                if nrn < nr or nrn < TOL:
                    ok = True
                    break
            except (ValueError, RuntimeError, ZeroDivisionError, OverflowError):
                pass
            lam *= 0.5
        if not ok:
            return None, it, nr
        x, r, nr = xn, rn, nrn
    return (x if nr < TOL else None), maxit, nr


X_DESIGN = None
ISO_HEALTH = {k: 0.0 for k in HEALTH_KEYS}


def solve_point(Tamb, Pamb, hp, mode, target, x0=None):
    """Solve one operating point, with homotopy from the design point if the
    direct Newton iteration fails.  Returns (x, iterations, residual, how)."""
    starts = []
    if x0 is not None:
        starts.append(x0)
    starts.append(X_DESIGN)
    total_it = 0
    for xs in starts:
        x, it, nr = newton(xs, (Tamb, Pamb, hp, mode, target))
        total_it += it
        if x is not None:
            return x, total_it, nr, 'direct'
    # homotopy in (ambient, health, target) from the design point
    for nsteps in (4, 8, 16, 32, 64):
        x = list(X_DESIGN)
        good = True
        for k in range(1, nsteps + 1):
            lam = k / nsteps
            Ta = ISO_T + lam * (Tamb - ISO_T)
            Pa = ISO_P + lam * (Pamb - ISO_P)
            hpl = {kk: lam * hp.get(kk, 0.0) for kk in HEALTH_KEYS}
            if mode == 'power':
                tg = PREF + lam * (target - PREF)
            else:
                tg = S['T4'] + lam * (target - S['T4'])
            xn, it, nr = newton(x, (Ta, Pa, hpl, mode, tg))
            total_it += it
            if xn is None:
                good = False
                break
            x = xn
        if good:
            return x, total_it, nr, 'homotopy%d' % nsteps
    return None, total_it, float('inf'), 'failed'


def operate(Tamb, Pamb, hp, load_frac, x0=None, allow_cap=True):
    """Set electrical power = load_frac * ISO rating; cap TIT at its ISO value."""
    target = load_frac * PREF
    x, it, nr, how = solve_point(Tamb, Pamb, hp, 'power', target, x0)
    capped = False
    if x is not None and allow_cap and x[2] > S['T4'] + 1e-9:
        xc, it2, nr2, how2 = solve_point(Tamb, Pamb, hp, 'tit', S['T4'], x)
        it += it2
        x, nr, how, capped = xc, nr2, how + '+cap:' + how2, True
    if x is None:
        return None
    res, st = engine(x, Tamb, Pamb, hp, 'tit' if capped else 'power',
                     S['T4'] if capped else target, full=True)
    st.update(x=x, iters=it, resid=max(abs(v) for v in res), how=how, capped=capped,
              load_target=load_frac, converged=True)
    return st


# =============================================================================
# Operating points
# =============================================================================
LOADS = [0.35, 0.43, 0.51, 0.59, 0.67, 0.75, 0.83, 0.91, 1.00]
# (ambient degC, barometer kPa) -- one synthetic "day" per load
BASE_DAYS = [(38.0, 99.30), (-5.0, 102.50), (22.0, 100.40), (7.0, 101.70), (33.0, 98.50),
             (0.0, 102.00), (15.0, 101.10), (4.0, 100.80), (28.0, 99.90)]
GRID_DAYS = [(35.0, 99.00), (12.0, 101.90), (27.0, 100.10), (-2.0, 102.20), (24.0, 100.00),
             (18.0, 100.60), (5.0, 101.30), (9.0, 101.50), (2.0, 101.60)]
BASE_T0 = datetime(2025, 3, 1, 0, 0, 0, tzinfo=timezone.utc)
GRID_T0 = datetime(2025, 6, 2, 0, 0, 0, tzinfo=timezone.utc)
LEVEL_SEED = 4242
NOISE_SEED = 20250301


def make_levels():
    lv = [dict()]
    for g in (1.0, 2.0, 3.0, 4.5):
        lv.append(dict(D_GC=g, D_EC=0.5 * g))
    for gt, et in ((0.7, 0.5), (1.4, 1.0), (2.1, 1.5)):
        lv.append(dict(D_GT=gt, D_ET=et))
    for gt, et in ((-0.7, 0.8), (-1.4, 1.6), (-2.1, 2.4)):
        lv.append(dict(D_GT=gt, D_ET=et))
    for gp, ep in ((-0.6, 0.6), (-1.2, 1.2), (-1.8, 1.8)):
        lv.append(dict(D_GP=gp, D_EP=ep))
    rng = random.Random(LEVEL_SEED)
    for _ in range(6):
        lv.append(dict(D_GC=round(rng.uniform(0.0, 4.0), 2), D_EC=round(rng.uniform(0.0, 2.0), 2),
                       D_GT=round(rng.uniform(-2.0, 2.0), 2), D_ET=round(rng.uniform(0.0, 2.5), 2),
                       D_GP=round(rng.uniform(-1.5, 0.5), 2), D_EP=round(rng.uniform(0.0, 2.0), 2)))
    return [{k: float(d.get(k, 0.0)) for k in HEALTH_KEYS} for d in lv]


# =============================================================================
# Output
# =============================================================================
MEAS_COLS = ['timestamp', 'AMB_T_F', 'AMB_P_PSIA', 'T1_F', 'P1_PSIA', 'NGG_RPM', 'NPT_RPM',
             'FUEL_LBH', 'CDP_PSIA', 'CDT_F', 'T48_F', 'EGT_F', 'MW', 'group'] + \
            ['true_' + k for k in HEALTH_KEYS]
# (kind, sigma, exact fmt, noisy fmt); kind 'abs' in column units, 'rel' fraction
SIG = {
    'AMB_T_F': ('abs', 1.0, '%.5f', '%.2f'), 'AMB_P_PSIA': ('rel', 0.0003, '%.7f', '%.4f'),
    'T1_F': ('abs', 1.0, '%.5f', '%.2f'), 'P1_PSIA': ('rel', 0.001, '%.7f', '%.4f'),
    'NGG_RPM': ('rel', 0.0002, '%.4f', '%.2f'), 'NPT_RPM': ('rel', 0.0002, '%.4f', '%.2f'),
    'FUEL_LBH': ('rel', 0.005, '%.4f', '%.2f'), 'CDP_PSIA': ('rel', 0.001, '%.6f', '%.4f'),
    'CDT_F': ('abs', 1.0, '%.5f', '%.2f'), 'T48_F': ('abs', 2.0, '%.5f', '%.2f'),
    'EGT_F': ('abs', 2.0, '%.5f', '%.2f'), 'MW': ('rel', 0.003, '%.7f', '%.5f'),
}


def measured(st):
    return {
        'AMB_T_F': k2f(st['Tamb']), 'AMB_P_PSIA': pa2psi(st['Pamb']), 'T1_F': k2f(st['T1']),
        'P1_PSIA': pa2psi(st['P1']), 'NGG_RPM': st['N_gg'], 'NPT_RPM': st['N_pt'],
        'FUEL_LBH': kgs2lbh(st['W_fuel']), 'CDP_PSIA': pa2psi(st['P3']), 'CDT_F': k2f(st['T3']),
        'T48_F': k2f(st['T48']), 'EGT_F': k2f(st['T5']), 'MW': st['P_elec'] / 1e6,
    }


INT_COLS = [
    ('timestamp', None), ('group', None), ('load_target_pct', '%.1f'), ('tit_capped', None),
    ('converged', None), ('newton_iters', '%d'), ('max_residual', '%.2e'), ('solve_path', None),
    ('Tamb_K', '%.4f'), ('Pamb_kPa', '%.5f'), ('P1_kPa', '%.5f'), ('Nc_rel', '%.6f'),
    ('N_gg_rpm', '%.3f'), ('beta', '%.6f'), ('surge_margin_pct', '%.4f'), ('vigv_deg', '%.4f'),
    ('bleed_frac', '%.6f'), ('W1_kgs', '%.5f'), ('W1c_kgs', '%.5f'), ('PR_c', '%.6f'),
    ('eta_c', '%.6f'), ('T3_K', '%.4f'), ('P3_kPa', '%.4f'), ('P_comp_MW', '%.5f'),
    ('W_bleed_kgs', '%.5f'), ('W_cool_ngv_kgs', '%.5f'), ('W_cool_rotor_kgs', '%.5f'),
    ('W31_kgs', '%.5f'), ('dp_comb_pct', '%.5f'), ('W_fuel_kgs', '%.7f'), ('FAR', '%.7f'),
    ('T4_TIT_K', '%.4f'), ('P4_kPa', '%.4f'), ('T41_SOT_K', '%.4f'), ('W41_kgs', '%.5f'),
    ('PR_hpt', '%.6f'), ('eta_hpt', '%.6f'), ('P_hpt_MW', '%.5f'), ('T45_K', '%.4f'),
    ('P45_kPa', '%.4f'), ('P48_kPa', '%.4f'), ('T48_K', '%.4f'), ('W45_kgs', '%.5f'),
    ('PR_pt', '%.6f'), ('eta_pt', '%.6f'), ('nu_over_nuopt_pt', '%.5f'), ('P_pt_MW', '%.5f'),
    ('P5_kPa', '%.4f'), ('T5_K', '%.4f'), ('P_ggloss_kW', '%.3f'), ('eta_gearbox', '%.6f'),
    ('eta_generator', '%.6f'), ('P_elec_MW', '%.6f'), ('eta_thermal', '%.6f'),
    ('heat_rate_kJkWh', '%.3f'), ('heat_rate_BtukWh', '%.3f'),
] + [('true_' + k, '%.2f') for k in HEALTH_KEYS]


def internal_row(ts, group, st, hp):
    v = {
        'timestamp': ts, 'group': group, 'load_target_pct': 100 * st['load_target'],
        'tit_capped': 'yes' if st['capped'] else 'no', 'converged': 'yes',
        'newton_iters': st['iters'], 'max_residual': st['resid'], 'solve_path': st['how'],
        'Tamb_K': st['Tamb'], 'Pamb_kPa': st['Pamb'] / 1e3, 'P1_kPa': st['P1'] / 1e3,
        'Nc_rel': st['Nc'], 'N_gg_rpm': st['N_gg'], 'beta': st['beta'],
        'surge_margin_pct': 100 * st['SM'], 'vigv_deg': st['vigv'], 'bleed_frac': st['bleed'],
        'W1_kgs': st['W1'], 'W1c_kgs': st['Wc'], 'PR_c': st['PR'], 'eta_c': st['eta_c'],
        'T3_K': st['T3'], 'P3_kPa': st['P3'] / 1e3, 'P_comp_MW': st['P_comp'] / 1e6,
        'W_bleed_kgs': st['W_bleed'], 'W_cool_ngv_kgs': st['W_ngv'], 'W_cool_rotor_kgs': st['W_rot'],
        'W31_kgs': st['W31'], 'dp_comb_pct': 100 * st['dp_comb'], 'W_fuel_kgs': st['W_fuel'],
        'FAR': st['FAR'], 'T4_TIT_K': st['T4'], 'P4_kPa': st['P4'] / 1e3, 'T41_SOT_K': st['T41'],
        'W41_kgs': st['W41'], 'PR_hpt': st['PR_hpt'], 'eta_hpt': st['eta_hpt'],
        'P_hpt_MW': st['P_hpt'] / 1e6, 'T45_K': st['T45'], 'P45_kPa': st['P45'] / 1e3,
        'P48_kPa': st['P48'] / 1e3, 'T48_K': st['T48'], 'W45_kgs': st['W45'], 'PR_pt': st['PR_pt'],
        'eta_pt': st['eta_pt'], 'nu_over_nuopt_pt': st['nu_pt'], 'P_pt_MW': st['P_pt'] / 1e6,
        'P5_kPa': st['P5'] / 1e3, 'T5_K': st['T5'], 'P_ggloss_kW': st['P_ggloss'] / 1e3,
        'eta_gearbox': st['eta_gb'], 'eta_generator': st['eta_gen'], 'P_elec_MW': st['P_elec'] / 1e6,
        'eta_thermal': st['eta_th'], 'heat_rate_kJkWh': st['HR_kJkWh'],
        'heat_rate_BtukWh': st['HR_kJkWh'] / KJ_PER_BTU,
    }
    for k in HEALTH_KEYS:
        v['true_' + k] = hp[k]
    out = []
    for c, f in INT_COLS:
        out.append(str(v[c]) if f is None else f % v[c])
    return ','.join(out)


def write_csv(path, header, lines):
    with open(path, 'w', newline='\n') as fh:
        fh.write(','.join(header) + '\n')
        for ln in lines:
            fh.write(ln + '\n')


def fmt_meas(ts, meas, group, hp, noisy):
    out = [ts]
    for c in MEAS_COLS[1:13]:
        out.append((SIG[c][3] if noisy else SIG[c][2]) % meas[c])
    out.append(group)
    out += ['%.2f' % hp[k] for k in HEALTH_KEYS]
    return ','.join(out)


def add_noise(meas, rng):
    nm = {}
    for c in MEAS_COLS[1:13]:
        kind, sig = SIG[c][0], SIG[c][1]
        g = rng.gauss(0.0, 1.0)
        nm[c] = meas[c] + sig * g if kind == 'abs' else meas[c] * (1.0 + sig * g)
    return nm


def iso(ts):
    return ts.strftime('%Y-%m-%dT%H:%M:%SZ')


# =============================================================================
# Checks
# =============================================================================
def energy_balance(st, hp):
    """Independent first-law closure from station values (W)."""
    W1, Wf = st['W1'], st['W_fuel']
    e_in = W1 * AIR.h(st['T1']) + Wf * FUEL.h(T_FUEL)
    m5 = st['m45']
    e_out = (st['W_bleed'] * AIR.h(st['T3']) + st['W5'] * m5.h(st['T5']) + st['P_pt'] +
             st['P_ggloss'] + (1 - D['ETA_B']) * Wf * LHV)
    mass = W1 + Wf - st['W_bleed'] - st['W5']
    return (e_in - e_out), mass


def main():
    t0 = time.time()
    global X_DESIGN
    T4d = design()
    X_DESIGN = [1.0, D['BETA_D'], T4d, S['PRH'], S['PRP']]
    res, dst = engine(X_DESIGN, ISO_T, ISO_P, ISO_HEALTH, 'power', PREF, full=True)
    design_resid = max(abs(v) for v in res)

    levels = make_levels()
    rng = random.Random(NOISE_SEED)
    log = []

    # ---------------- baseline
    b_ex, b_no, b_in, base_states = [], [], [], []
    x0 = None
    nfail = 0
    for i, (lf, (tc, pk)) in enumerate(zip(LOADS, BASE_DAYS)):
        ts = iso(BASE_T0 + timedelta(hours=i))
        st = operate(tc + 273.15, pk * 1e3, ISO_HEALTH, lf, x0)
        if st is None:
            nfail += 1
            log.append('baseline row %d (%s) FAILED' % (i, ts))
            continue
        x0 = st['x']
        base_states.append((ts, lf, tc, pk, st))
        m = measured(st)
        b_ex.append(fmt_meas(ts, m, 'baseline', ISO_HEALTH, False))
        b_no.append(fmt_meas(ts, add_noise(m, rng), 'baseline', ISO_HEALTH, True))
        b_in.append(internal_row(ts, 'baseline', st, ISO_HEALTH))
    write_csv(os.path.join(OUT, 'baseline_exact.csv'), MEAS_COLS, b_ex)
    write_csv(os.path.join(OUT, 'baseline_noisy.csv'), MEAS_COLS, b_no)
    write_csv(os.path.join(OUT, 'baseline_internal.csv'), [c for c, _ in INT_COLS], b_in)

    # ---------------- grid
    g_ex, g_no, g_in, grid_states = [], [], [], []
    k = 0
    for li, hp in enumerate(levels):
        grp = 'level%02d' % li
        x0 = None
        for j, (lf, (tc, pk)) in enumerate(zip(LOADS, GRID_DAYS)):
            ts = iso(GRID_T0 + timedelta(hours=k))
            k += 1
            st = operate(tc + 273.15, pk * 1e3, hp, lf, x0)
            if st is None:
                nfail += 1
                log.append('grid %s load %.0f%% FAILED' % (grp, 100 * lf))
                continue
            x0 = st['x']
            grid_states.append((ts, grp, lf, tc, pk, hp, st))
            m = measured(st)
            g_ex.append(fmt_meas(ts, m, grp, hp, False))
            g_no.append(fmt_meas(ts, add_noise(m, rng), grp, hp, True))
            g_in.append(internal_row(ts, grp, st, hp))
    write_csv(os.path.join(OUT, 'grid_exact.csv'), MEAS_COLS, g_ex)
    write_csv(os.path.join(OUT, 'grid_noisy.csv'), MEAS_COLS, g_no)
    write_csv(os.path.join(OUT, 'grid_internal.csv'), [c for c, _ in INT_COLS], g_in)

    # ---------------- design.txt
    write_design(dst)

    # ---------------- checks.txt
    write_checks(dst, design_resid, base_states, grid_states, levels, nfail, log, t0)
    print('done in %.1f s, failures: %d' % (time.time() - t0, nfail))


def write_design(st):
    W5 = st['W5']
    L = []
    L.append('INDEP2 two-shaft industrial gas turbine generator set -- performance datasheet')
    L.append('=' * 78)
    L.append('Configuration : single-spool axial compressor (variable inlet guide vanes,')
    L.append('                handling bleed valve) + annular dry combustor + 2-stage air-cooled')
    L.append('                HP turbine (gas generator) + free power turbine, reduction gearbox,')
    L.append('                4-pole 60 Hz generator (1800 rpm).')
    L.append('')
    L.append('ISO rating conditions: 15 degC (59 F), 101.325 kPa (14.696 psia), dry air,')
    L.append('  inlet loss %.1f kPa (%.1f inH2O), exhaust loss %.1f kPa (%.1f inH2O), natural gas below.'
             % (D['DP_IN'] / 1e3, D['DP_IN'] / 249.0889, D['DP_EX'] / 1e3, D['DP_EX'] / 249.0889))
    L.append('')
    L.append('Performance at ISO, base load (generator terminals):')
    L.append('  Electrical power output ........ %8.3f MW' % (st['P_elec'] / 1e6))
    L.append('  Heat rate (LHV) ................ %8.0f kJ/kWh   (%.0f Btu/kWh)'
             % (st['HR_kJkWh'], st['HR_kJkWh'] / KJ_PER_BTU))
    L.append('  Thermal efficiency (LHV) ....... %8.2f %%' % (100 * st['eta_th']))
    L.append('  Fuel flow ...................... %8.4f kg/s      (%.0f lb/h)' % (st['W_fuel'], kgs2lbh(st['W_fuel'])))
    L.append('  Fuel energy input (LHV) ........ %8.3f MW' % (st['W_fuel'] * LHV / 1e6))
    L.append('  Compressor pressure ratio ...... %8.2f' % st['PR'])
    L.append('  Compressor inlet air flow ...... %8.2f kg/s      (%.1f lb/s)' % (st['W1'], st['W1'] / KG_PER_LB))
    L.append('  Compressor discharge pressure .. %8.1f kPa       (%.1f psia)' % (st['P3'] / 1e3, pa2psi(st['P3'])))
    L.append('  Compressor discharge temp. ..... %8.1f degC      (%.1f F)' % (k2c(st['T3']), k2f(st['T3'])))
    L.append('  Exhaust gas flow ............... %8.2f kg/s      (%.0f lb/h)' % (W5, kgs2lbh(W5)))
    L.append('  Exhaust temperature (PT exit) .. %8.1f degC      (%.1f F)' % (k2c(st['T5']), k2f(st['T5'])))
    L.append('  PT inlet temperature (T48) ..... %8.1f degC      (%.1f F)' % (k2c(st['T48']), k2f(st['T48'])))
    L.append('  Turbine inlet temperature ...... %8.1f degC      (%.1f F, %.1f K)'
             % (k2c(st['T4']), k2f(st['T4']), st['T4']))
    L.append('     (TIT = combustor exit / first-stage NGV inlet, before any cooling air;')
    L.append('      control limit: the unit is temperature-limited at this value)')
    L.append('  Gas generator speed ............ %8.0f rpm' % st['N_gg'])
    L.append('  Power turbine speed ............ %8.0f rpm (synchronous, held by the governor)' % st['N_pt'])
    L.append('  Generator speed ................ %8.0f rpm (gearbox ratio %.4f)' % (D['NGEN'], D['NPT'] / D['NGEN']))
    L.append('')
    L.append('Cooling / secondary air (fractions of compressor inlet flow, from compressor exit):')
    L.append('  HP turbine NGV cooling ......... %5.1f %%' % (100 * D['F_NGV']))
    L.append('  HP turbine rotor cooling ....... %5.1f %%' % (100 * D['F_ROT']))
    L.append('  Handling (anti-surge) bleed .... 0 %% at load; opens (up to %.0f %% overboard) below'
             % (100 * BLEED_MAX))
    L.append('                                   %.0f %% corrected GG speed (start-up / low speed only)' % (100 * BLEED_N0))
    L.append('  Variable inlet guide vanes ..... fully open above %.0f %% corrected GG speed,' % (100 * VIGV_N0))
    L.append('                                   closing on corrected speed below it')
    L.append('')
    L.append('Drive train at ISO base load:')
    L.append('  Gearbox efficiency ............. %6.2f %%' % (100 * st['eta_gb']))
    L.append('  Generator efficiency ........... %6.2f %%  (97.0 %% at 30 %% load), unity power factor basis'
             % (100 * st['eta_gen']))
    L.append('  PT shaft power ................. %8.3f MW' % (st['P_pt'] / 1e6))
    L.append('')
    L.append('Fuel: pipeline natural gas, supplied to the burners at 25 degC')
    L.append('  Composition (mol %%): CH4 %.1f, C2H6 %.1f, C3H8 %.1f, N2 %.1f, CO2 %.1f'
             % tuple(100 * FUEL_X[s] for s in ['CH4', 'C2H6', 'C3H8', 'N2', 'CO2']))
    L.append('  Molar mass ..................... %8.3f kg/kmol' % (FUEL.M * 1e3))
    L.append('  Lower heating value (25 degC) .. %8.0f kJ/kg    (%.0f Btu/lb)'
             % (LHV / 1e3, LHV / 1e3 / KJ_PER_BTU * KG_PER_LB))
    L.append('  Stoichiometric fuel/air ratio .. %8.5f' % STOICH_FAR)
    L.append('  Combustion efficiency .......... %8.3f' % D['ETA_B'])
    L.append('')
    L.append('Pressure losses at ISO base load: inlet %.1f kPa, combustor %.1f %% of CDP,'
             % (D['DP_IN'] / 1e3, 100 * D['DP_B']))
    L.append('  exhaust system %.1f kPa.  Mechanical: GG shaft loss %.1f %% of compressor power.'
             % (D['DP_EX'] / 1e3, 100 * D['GG_LOSS']))
    L.append('')
    L.append('Site rating: output falls with ambient temperature; on warm days base load is')
    L.append('set by the TIT limit above (power then below the ISO rating).')
    with open(os.path.join(OUT, 'design.txt'), 'w') as fh:
        fh.write('\n'.join(L) + '\n')


def write_checks(dst, design_resid, base_states, grid_states, levels, nfail, log, t0):
    L = []
    L.append('indep2 self-checks (generated by sim.py)')
    L.append('=' * 78)
    L.append('')
    L.append('1. Design point / consistency')
    L.append('   design TIT solved for %.3f MW: T4 = %.4f K; off-design residual at the design'
             % (PREF / 1e6, S['T4']))
    L.append('   vector with ISO conditions = %.2e (must be ~0)' % design_resid)
    L.append('   LHV of the fuel from GRI-Mech 3.0 formation enthalpies: %.1f kJ/kg (%.2f kJ/mol)'
             % (LHV / 1e3, LHV_MOLAR / 1e3))
    L.append('   elec chain: shaft_from_elec(elec_from_shaft(15 MW)) - 15 MW = %.2e W'
             % (shaft_from_elec(elec_from_shaft(15e6)) - 15e6))
    L.append('   generator efficiency at 30 %% load = %.4f, at 100 %% = %.4f'
             % (0.3 * PREF / (0.3 * PREF + PREF * (D['GEN0'] + D['GEN2'] * 0.09)),
                PREF / (PREF + PREF * (D['GEN0'] + D['GEN2']))))
    L.append('')
    L.append('2. Energy and mass balance closure, every row (independent recomputation of')
    L.append('   inflow enthalpy vs exhaust + bleed enthalpy + PT shaft + GG loss + unburnt fuel)')
    worst_e, worst_m = 0.0, 0.0
    for item in base_states:
        st = item[-1]
        e, m = energy_balance(st, ISO_HEALTH)
        worst_e = max(worst_e, abs(e) / (st['W_fuel'] * LHV))
        worst_m = max(worst_m, abs(m) / st['W1'])
    for item in grid_states:
        st = item[-1]
        e, m = energy_balance(st, item[5])
        worst_e = max(worst_e, abs(e) / (st['W_fuel'] * LHV))
        worst_m = max(worst_m, abs(m) / st['W1'])
    L.append('   max |energy error| / fuel energy = %.2e ; max |mass error| / W1 = %.2e'
             % (worst_e, worst_m))
    e, m = energy_balance(dst, ISO_HEALTH)
    L.append('   ISO design point: energy error %.3e W of %.3f MW fuel energy' % (e, dst['W_fuel'] * LHV / 1e6))
    L.append('')

    # ---------- response table
    L.append('3. Response of each measured signal to +1 (percent point) of each health')
    L.append('   parameter, ISO day, constant %.1f MW electrical (TIT not capped here),' % (PREF / 1e6))
    L.append('   by central difference (+1/-1)/2; plant units.')
    sigs = ['P1_PSIA', 'NGG_RPM', 'FUEL_LBH', 'CDP_PSIA', 'CDT_F', 'T48_F', 'EGT_F']
    m0 = measured(dst)
    L.append('   %-6s' % 'param' + ''.join('%11s' % s for s in sigs) + '%10s' % 'TIT_K' + '%9s' % 'SM_pts')
    L.append('   %-6s' % 'base' + ''.join('%11.3f' % m0[s] for s in sigs) + '%10.2f' % dst['T4']
             + '%9.2f' % (100 * dst['SM']))
    resp = {}
    for k in HEALTH_KEYS:
        sts = []
        for sgn in (1.0, -1.0):
            hp = dict(ISO_HEALTH)
            hp[k] = sgn
            st = operate(ISO_T, ISO_P, hp, 1.0, X_DESIGN, allow_cap=False)
            sts.append(st)
        mp, mm = measured(sts[0]), measured(sts[1])
        resp[k] = {s: (mp[s] - mm[s]) / 2 for s in sigs}
        resp[k]['T4'] = (sts[0]['T4'] - sts[1]['T4']) / 2
        resp[k]['SM'] = 100 * (sts[0]['SM'] - sts[1]['SM']) / 2
        L.append('   %-6s' % ('+' + k) + ''.join('%11.4f' % resp[k][s] for s in sigs)
                 + '%10.3f' % resp[k]['T4'] + '%9.3f' % resp[k]['SM'])
    L.append('   (units: psia, rpm, lb/h, psia, F, F, F, K, surge-margin points; NPT and MW fixed,')
    L.append('    T1 and ambient unaffected)')
    L.append('')

    # ---------- robustness
    L.append('4. Solver robustness')
    nb, ng = len(base_states), len(grid_states)
    L.append('   rows converged: baseline %d/9, grid %d/180 ; failures: %d' % (nb, ng, nfail))
    allst = [it[-1] for it in base_states] + [it[-1] for it in grid_states]
    if allst:
        L.append('   max final residual %.2e (tolerance %.0e), max Newton iterations %d'
                 % (max(s['resid'] for s in allst), TOL, max(s['iters'] for s in allst)))
        paths = {}
        for s in allst:
            p = s['how'].split('+')[0]
            paths[p] = paths.get(p, 0) + 1
        L.append('   solve paths: ' + ', '.join('%s %d' % kv for kv in sorted(paths.items())))
    for ln in log:
        L.append('   ' + ln)
    capped_b = [(it[0], it[1], it[4]['P_elec']) for it in base_states if it[4]['capped']]
    capped_g = [(it[0], it[1], it[2], it[6]['P_elec']) for it in grid_states if it[6]['capped']]
    L.append('   TIT-capped baseline rows: %d' % len(capped_b))
    for ts, lf, pe in capped_b:
        L.append('     %s target %.0f %% -> reached %.4f MW (%.2f %% of ISO rating)'
                 % (ts, 100 * lf, pe / 1e6, 100 * pe / PREF))
    L.append('   TIT-capped grid rows: %d' % len(capped_g))
    for ts, grp, lf, pe in capped_g:
        L.append('     %s %s target %.0f %% -> reached %.4f MW (%.2f %%)'
                 % (ts, grp, 100 * lf, pe / 1e6, 100 * pe / PREF))
    # stress sweep
    nok, ntot, worst = 0, 0, 0
    hp_bad = dict(D_GC=5.0, D_EC=2.5, D_GT=2.5, D_ET=3.0, D_GP=-2.0, D_EP=2.5)
    hp_ero = dict(D_GC=0.0, D_EC=1.0, D_GT=-2.5, D_ET=3.0, D_GP=1.0, D_EP=0.0)
    for hp in (ISO_HEALTH, {k: hp_bad.get(k, 0.0) for k in HEALTH_KEYS}, {k: hp_ero.get(k, 0.0) for k in HEALTH_KEYS}):
        for tc in (-15.0, 15.0, 45.0):
            for lf in (0.25, 0.35, 0.5, 0.7, 0.9, 1.0, 1.1):
                ntot += 1
                st = operate(tc + 273.15, 101.325e3, hp, lf, None)
                if st is not None:
                    nok += 1
                    worst = max(worst, st['iters'])
    L.append('   stress sweep (health: healthy, heavy fouling, erosion mix; ambient -15/15/45 C;')
    L.append('   loads 25..110 %%, cold start from the design point): %d/%d converged, max iters %d'
             % (nok, ntot, worst))
    L.append('')

    # ---------- operating line
    L.append('5. Baseline operating line (healthy engine)')
    hdr = ('  load  Tamb  Pamb   NGG    Nc    beta   SM  VIGV bleed   W1     PR    TIT    T48    EGT   fuel   eta  MW   cap')
    L.append(hdr)
    L.append('   %    degC  kPa   rpm     -      -     %   deg   %    kg/s    -      K      K      K    kg/s    %   ')
    for ts, lf, tc, pk, st in base_states:
        L.append('%5.0f %5.1f %6.2f %6.0f %6.4f %5.3f %5.1f %4.1f %4.1f %6.2f %6.3f %6.1f %6.1f %6.1f %6.4f %5.2f %5.2f %s'
                 % (100 * lf, tc, pk, st['N_gg'], st['Nc'], st['beta'], 100 * st['SM'], st['vigv'],
                    100 * st['bleed'], st['W1'], st['PR'], st['T4'], st['T48'], st['T5'],
                    st['W_fuel'], 100 * st['eta_th'], st['P_elec'] / 1e6, 'CAP' if st['capped'] else ''))
    L.append('')
    L.append('   same loads on the ISO day (healthy, for trend reference):')
    L.append(hdr)
    x0 = X_DESIGN
    for lf in reversed(LOADS):
        st = operate(ISO_T, ISO_P, ISO_HEALTH, lf, x0)
        x0 = st['x']
        L.append('%5.0f %5.1f %6.2f %6.0f %6.4f %5.3f %5.1f %4.1f %4.1f %6.2f %6.3f %6.1f %6.1f %6.1f %6.4f %5.2f %5.2f %s'
                 % (100 * lf, 15.0, 101.325, st['N_gg'], st['Nc'], st['beta'], 100 * st['SM'], st['vigv'],
                    100 * st['bleed'], st['W1'], st['PR'], st['T4'], st['T48'], st['T5'],
                    st['W_fuel'], 100 * st['eta_th'], st['P_elec'] / 1e6, 'CAP' if st['capped'] else ''))
    L.append('')
    L.append('6. Other component states along the baseline (eta_c, eta_hpt, eta_pt, PR_hpt, PR_pt)')
    for ts, lf, tc, pk, st in base_states:
        L.append('   %3.0f %%  eta_c %.4f  eta_hpt %.4f  eta_pt %.4f  PR_hpt %.3f  PR_pt %.3f  nu/nuopt_pt %.3f'
                 % (100 * lf, st['eta_c'], st['eta_hpt'], st['eta_pt'], st['PR_hpt'], st['PR_pt'], st['nu_pt']))
    L.append('')
    L.append('7. Degradation levels of the grid (percent; positive = degraded)')
    L.append('   level ' + ''.join('%8s' % k for k in HEALTH_KEYS))
    for li, hp in enumerate(levels):
        L.append('   %02d    ' % li + ''.join('%8.2f' % hp[k] for k in HEALTH_KEYS))
    with open(os.path.join(OUT, 'checks.txt'), 'w') as fh:
        fh.write('\n'.join(L) + '\n')


if __name__ == '__main__':
    main()
