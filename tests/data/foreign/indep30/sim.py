#!/usr/bin/env python3
"""
Independent steady-state simulator of a ~30 MW two-shaft industrial gas turbine
(gas generator = axial compressor with VIGV + combustor + HP turbine, free power
turbine driving a centrifugal pipeline compressor, P ~ N2^3).

Pure Python 3, standard library only.  `python3 sim.py` regenerates every output
file of this directory deterministically.

Station numbering used throughout (and in README.md):
  0   ambient
  1   compressor inlet face (after inlet duct loss)
  2   compressor discharge (before cooling bleeds)
  3   combustor exit (TIT)
  31  HPT rotor inlet (after mixing of the 5 % NGV cooling air)  ("SOT")
  33  HPT rotor exit, before rotor-cooling air mixing
  34  HPT exit after mixing of the 3 % rotor cooling air (measured P34/T34)
  35  PT inlet (after the inter-turbine duct loss)
  4   PT exit / exhaust collector total (measured P4/T4)
Units inside the model: K, kPa, kg/s, kJ/kg, kW, rpm.
"""
import math
import os
import random

import time

HERE = os.path.dirname(os.path.abspath(__file__))

# =============================================================================
# 1. THERMODYNAMICS
# =============================================================================
RU = 8.314462618          # kJ/(kmol K)
T_REF = 298.15            # K, reference for sensible enthalpy / LHV
MW = {'N2': 28.0134, 'O2': 31.9988, 'AR': 39.948, 'CO2': 44.0095,
      'H2O': 18.01528, 'CH4': 16.04246}
# NASA 7-coefficient polynomials (GRI-Mech 3.0 thermo data), (low 200/300-1000 K, high 1000-5000 K)
NASA7 = {
    'N2': ((3.298677, 1.4082404e-03, -3.963222e-06, 5.641515e-09, -2.444854e-12, -1020.8999, 3.950372),
           (2.92664, 1.4879768e-03, -5.68476e-07, 1.0097038e-10, -6.753351e-15, -922.7977, 5.980528)),
    'O2': ((3.78245636, -2.99673416e-03, 9.84730201e-06, -9.68129509e-09, 3.24372837e-12, -1063.94356, 3.65767573),
           (3.28253784, 1.48308754e-03, -7.57966669e-07, 2.09470555e-10, -2.16717794e-14, -1088.45772, 5.45323129)),
    'AR': ((2.5, 0.0, 0.0, 0.0, 0.0, -745.375, 4.366),
           (2.5, 0.0, 0.0, 0.0, 0.0, -745.375, 4.366)),
    'CO2': ((2.35677352, 8.98459677e-03, -7.12356269e-06, 2.45919022e-09, -1.43699548e-13, -48371.9697, 9.90105222),
            (3.85746029, 4.41437026e-03, -2.21481404e-06, 5.23490188e-10, -4.72084164e-14, -48759.166, 2.27163806)),
    'H2O': ((4.19864056, -2.0364341e-03, 6.52040211e-06, -5.48797062e-09, 1.77197817e-12, -30293.7267, -0.849032208),
            (3.03399249, 2.17691804e-03, -1.64072518e-07, -9.7041987e-11, 1.68200992e-14, -30004.2971, 4.9667701)),
    'CH4': ((5.14987613, -1.36709788e-02, 4.91800599e-05, -4.84743026e-08, 1.66693956e-11, -10246.6476, -4.64130376),
            (0.074851495, 1.33909467e-02, -5.73285809e-06, 1.22292535e-09, -1.0181523e-13, -9468.34459, 18.437318)),
}


def nasa_cp_R(a, T):
    return a[0] + T * (a[1] + T * (a[2] + T * (a[3] + T * a[4])))


def nasa_h_RT(a, T):
    return a[0] + T * (a[1] / 2 + T * (a[2] / 3 + T * (a[3] / 4 + T * a[4] / 5))) + a[5] / T


def nasa_s_R(a, T):
    return a[0] * math.log(T) + T * (a[1] + T * (a[2] / 2 + T * (a[3] / 3 + T * a[4] / 4))) + a[6]


def _rng(sp, T):
    lo, hi = NASA7[sp]
    return lo if T < 1000.0 else hi


def nasa_cp(sp, T):
    return nasa_cp_R(_rng(sp, T), T)


def nasa_h(sp, T):          # absolute (incl. formation) h/R [K]
    return nasa_h_RT(_rng(sp, T), T) * T


def nasa_s(sp, T):
    return nasa_s_R(_rng(sp, T), T)


# The GRI high-range constants a6, a7 are re-adjusted (by < 0.01 J/mol, < 1e-5 J/mol/K) so
# that h and s0 are exactly continuous at the 1000 K range joint (cp is continuous to the
# printed digits); the property functions are then C1 with a negligible cp' kink, which the
# Newton solver does not notice.
NASA_SHIFT = {}
for _sp, (_lo, _hi) in list(NASA7.items()):
    _hi = list(_hi)
    _dh = (nasa_h_RT(_lo, 1000.0) - nasa_h_RT(_hi, 1000.0)) * 1000.0
    _ds = nasa_s_R(_lo, 1000.0) - nasa_s_R(_hi, 1000.0)
    NASA_SHIFT[_sp] = (_dh * RU, _ds * RU)       # J/mol, J/mol/K
    _hi[5] += _dh
    _hi[6] += _ds
    NASA7[_sp] = (_lo, tuple(_hi))
T_MID = 1000.0

# Dry air (mole fractions) and methane combustion products per kg of air
X_AIR = {'N2': 0.78084, 'O2': 0.20946, 'AR': 0.00934, 'CO2': 0.00036}
M_AIR = sum(x * MW[s] for s, x in X_AIR.items())
N_AIR = {s: x / M_AIR for s, x in X_AIR.items()}                  # kmol per kg air
N_FUEL_DELTA = {'CO2': 1.0 / MW['CH4'], 'H2O': 2.0 / MW['CH4'], 'O2': -2.0 / MW['CH4']}  # kmol per kg CH4 burnt


def _mix_coefs(nmol, rng):
    """NASA coefficients of a mixture, multiplied by R_u*n so that cp = poly in kJ/K"""
    c = [0.0] * 7
    for s, n in nmol.items():
        for k in range(7):
            c[k] += n * RU * NASA7[s][rng][k]
    return c


A_COEF = (_mix_coefs(N_AIR, 0), _mix_coefs(N_AIR, 1))            # 1 kg of air
B_COEF = (_mix_coefs(N_FUEL_DELTA, 0), _mix_coefs(N_FUEL_DELTA, 1))  # change per kg CH4 burnt
R_A = RU * sum(N_AIR.values())
R_B = RU * sum(N_FUEL_DELTA.values())
FUEL_COEF = (_mix_coefs({'CH4': 1.0 / MW['CH4']}, 0), _mix_coefs({'CH4': 1.0 / MW['CH4']}, 1))


class Gas:
    """Dry air (f=0) or products of complete CH4 combustion at fuel-air ratio f, per kg of mixture.
    h = sensible enthalpy relative to 298.15 K [kJ/kg]; s = s0(T) relative to 298.15 K [kJ/kg/K]."""
    __slots__ = ('f', 'lo', 'hi', 'R', 'H0', 'S0')

    def __init__(self, f=0.0, coef=None, R=None):
        self.f = f
        if coef is None:
            coef = tuple([(a + f * b) / (1.0 + f) for a, b in zip(A_COEF[i], B_COEF[i])] for i in (0, 1))
            R = (R_A + f * R_B) / (1.0 + f)
        self.lo, self.hi = coef
        self.R = R
        self.H0 = 0.0
        self.S0 = 0.0
        self.H0 = self.h(T_REF)
        self.S0 = self.s(T_REF)

    def cp(self, T):
        a = self.lo if T < T_MID else self.hi
        return a[0] + T * (a[1] + T * (a[2] + T * (a[3] + T * a[4])))

    def h(self, T):
        a = self.lo if T < T_MID else self.hi
        return a[0] * T + T * T * (a[1] / 2 + T * (a[2] / 3 + T * (a[3] / 4 + T * a[4] / 5))) + a[5] - self.H0

    def s(self, T):
        a = self.lo if T < T_MID else self.hi
        return a[0] * math.log(T) + T * (a[1] + T * (a[2] / 2 + T * (a[3] / 3 + T * a[4] / 4))) + a[6] - self.S0

    def T_from_h(self, h, T=None):
        if T is None:
            T = 300.0 + h / 1.1
        for _ in range(60):
            dT = (self.h(T) - h) / self.cp(T)
            T -= dT
            if abs(dT) < 1e-11 * T:
                break
        return T

    def T_from_s(self, s, T=None):
        if T is None:
            T = 600.0
        for _ in range(60):
            dT = (self.s(T) - s) * T / self.cp(T)
            T -= dT
            if abs(dT) < 1e-11 * T:
                break
        return T


AIR = Gas(0.0)
FUEL = Gas(coef=FUEL_COEF, R=RU / MW['CH4'])


def compress(gas, T1, PR, eta):
    """isentropic-efficiency compression with the entropy function; returns T2, dh"""
    s2s = gas.s(T1) + gas.R * math.log(PR)
    T2s = gas.T_from_s(s2s, T1 * PR ** 0.28)
    h1 = gas.h(T1)
    dhs = gas.h(T2s) - h1
    dh = dhs / eta
    T2 = gas.T_from_h(h1 + dh, T2s + dh - dhs)
    return T2, dh, dhs


def expand(gas, T1, PR, eta):
    """turbine expansion by total pressure ratio PR (>1); returns T2, dh (positive work), dhs"""
    s2s = gas.s(T1) - gas.R * math.log(PR)
    T2s = gas.T_from_s(s2s, T1 * PR ** -0.25)
    h1 = gas.h(T1)
    dhs = h1 - gas.h(T2s)
    dh = eta * dhs
    T2 = gas.T_from_h(h1 - dh, T2s + (dhs - dh) / 1.2)
    return T2, dh, dhs


def lhv_from_nasa():
    """LHV of CH4 at 298.15 K from the NASA formation enthalpies [kJ/kg] (check only)"""
    H = lambda sp: nasa_h(sp, T_REF) * RU       # kJ/kmol
    return (H('CH4') + 2 * H('O2') - H('CO2') - 2 * H('H2O')) / MW['CH4']


GB = Gas(coef=B_COEF, R=R_B)      # 'gas' whose coefficients are the per-kg-fuel product change


def expand_fn(gas, T1, PR, eta_of_dhs):
    """expansion where the efficiency depends on the isentropic enthalpy drop"""
    s2s = gas.s(T1) - gas.R * math.log(PR)
    T2s = gas.T_from_s(s2s, T1 * PR ** -0.25)
    h1 = gas.h(T1)
    dhs = h1 - gas.h(T2s)
    eta = eta_of_dhs(dhs)
    dh = eta * dhs
    T2 = gas.T_from_h(h1 - dh, T2s + (dhs - dh) / 1.2)
    return T2, dh, dhs, eta


def combustor_far(T2, T3, eta_b, lhv, T_fuel):
    """fuel-air ratio (kg fuel / kg combustor air) from the enthalpy balance
       h_air(T2) + f (eta_b LHV + h_fuel(Tf)) = h_air(T3) + f hB(T3)  (all sensible, 298.15 K ref)"""
    return (AIR.h(T3) - AIR.h(T2)) / (eta_b * lhv + FUEL.h(T_fuel) - GB.h(T3))


def mix_T(streams, gas_out, Tguess):
    """adiabatic mixing: streams = [(W, gas, T), ...] -> T of the mixture (gas_out)"""
    W = sum(s[0] for s in streams)
    h = sum(s[0] * s[1].h(s[2]) for s in streams) / W
    return gas_out.T_from_h(h, Tguess)


# =============================================================================
# 2. DESIGN SPECIFICATION (vendor-datasheet-like inputs)
# =============================================================================
ISO_T, ISO_P = 288.15, 101.325


class Spec:
    N1 = 9950.0            # rpm, gas-generator design speed
    N2 = 5500.0            # rpm, PT speed at 100 % load
    W1 = 87.0              # kg/s compressor inlet air flow at ISO full load
    PR = 18.5              # compressor pressure ratio P2/P1
    POWER = 30000.0        # kW PT shaft power = "100 % load"
    DP_INLET = 1.0         # kPa inlet duct loss at design
    DP_COMB = 0.04         # combustor dP/P2 at design
    DP_ITD = 0.01          # inter-turbine duct dP/P34 at design
    DP_EXH = 3.0           # kPa exhaust/stack loss at design (P4 - P0)
    F_NGV = 0.05           # HPT nozzle cooling (fraction of W1), mixes before the HPT rotor
    F_ROT = 0.03           # HPT rotor cooling (fraction of W1), mixes at HPT exit
    ETA_B = 0.998          # combustion efficiency
    LHV = 50000.0          # kJ/kg methane
    T_FUEL = 298.15        # K fuel supply temperature
    ETA_HPT = 0.885        # HPT isentropic (total-total) efficiency at design
    ETA_PT = 0.905         # PT isentropic (total-total) efficiency at design
    ETA_MGG = 0.99         # GG mechanical efficiency (compressor power = 0.99 HPT power)
    ETA_MPT = 0.995        # PT mechanical efficiency (shaft power = 0.995 PT aero power)
    BETA_C = 0.50          # compressor map auxiliary coordinate at design


# =============================================================================
# 3. COMPONENT MAPS (own analytic forms)
# =============================================================================
class CMap:
    """Axial compressor.  n = corrected speed / design corrected speed; beta in [0,1]
    (0 = surge line, 1 = choke end of the speed line)."""
    a, k = 2.2, 0.3                # choke flow m_c(n) = (1+k) n^a / (1 + k n^a)
    w0, w1 = 0.04, 0.35            # speed-line width (m_c - m_s)/m_c = w0 + w1 (1 - n)
    b = 2.8                        # surge pressure-ratio rise (raw) PR_s - 1 = n^b
    rc = 0.55                      # PR-1 at the choke end = rc * (PR_s - 1)
    eta_pk, n_pk, b_pk = 0.880, 0.97, 0.45
    ab2, ab3, an2 = 0.45, 0.30, 0.60
    vg_hi, vg_lo, vg_ang, vg_flow, vg_eta = 0.93, 0.70, -20.0, 0.11, 0.015
    m_scale = 1.0                  # set by the design point
    p_scale = 1.0

    @staticmethod
    def vigv_s(n):
        """VIGV closure fraction 0 (open, n >= 0.93) .. 1 (-20 deg, n <= 0.70): C2 'smootherstep'"""
        x = (CMap.vg_hi - n) / (CMap.vg_hi - CMap.vg_lo)
        if x <= 0.0:
            return 0.0
        if x >= 1.0:
            return 1.0
        return x * x * x * (10.0 + x * (-15.0 + 6.0 * x))

    @staticmethod
    def line(n):
        """raw choke flow, surge flow, surge PR, choke-end PR of speed line n (VIGV open)"""
        c = CMap
        na = n ** c.a
        mc = (1.0 + c.k) * na / (1.0 + c.k * na)
        ms = mc * (1.0 - (c.w0 + c.w1 * (1.0 - n)))
        ps = 1.0 + n ** c.b
        pc = 1.0 + c.rc * (ps - 1.0)
        return mc, ms, ps, pc

    @staticmethod
    def raw(n, beta):
        c = CMap
        mc, ms, ps, pc = c.line(n)
        phi = 0.5 * math.pi * beta
        m = ms + (mc - ms) * math.sin(phi)
        p = pc + (ps - pc) * math.cos(phi)
        x = beta - c.b_pk
        eta = c.eta_pk - c.ab2 * x * x - c.ab3 * x * x * x - c.an2 * (n - c.n_pk) ** 2
        return m, p, eta

    @staticmethod
    def evaluate(n, beta, dgc=0.0, dec=0.0):
        """-> corrected flow [kg/s], PR, isentropic efficiency, VIGV angle [deg]"""
        c = CMap
        m, p, eta = c.raw(n, beta)
        s = c.vigv_s(n)
        wc = c.m_scale * m * (1.0 - c.vg_flow * s) * (1.0 - dgc / 100.0)
        PR = 1.0 + c.p_scale * (p - 1.0)
        eta = (eta - c.vg_eta * s) * (1.0 - dec / 100.0)
        return wc, PR, eta, c.vg_ang * s + 0.0

    @staticmethod
    def surge(n, dgc=0.0):
        c = CMap
        mc, ms, ps, pc = c.line(n)
        return (c.m_scale * ms * (1.0 - c.vg_flow * c.vigv_s(n)) * (1.0 - dgc / 100.0),
                1.0 + c.p_scale * (ps - 1.0))

    @staticmethod
    def surge_margin(wc, PR, dgc=0.0):
        """Walsh & Fletcher: SM = (PR_surge(at same corrected flow) - PR) / PR  [%]"""
        lo, hi = 0.2, 1.6
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if CMap.surge(mid, dgc)[0] < wc:
                lo = mid
            else:
                hi = mid
        return 100.0 * (CMap.surge(0.5 * (lo + hi), dgc)[1] / PR - 1.0)


class TMap:
    """Turbine: flow capacity W sqrt(T_in)/P_in = FC * sqrt(1 - PR^-a) * (1 + kn (1 - n_t))
       (generalised Stodola ellipse, choking for a -> large), n_t = corrected speed rel. design;
       efficiency = eta_d * (1 - ae (nu - 1)^2), nu = (U/C0)/(U/C0)_design
                  = (N/N_d) * sqrt(dh_is,d / dh_is)."""

    def __init__(self, a, kn, ae, eta_d):
        self.a, self.kn, self.ae, self.eta_d = a, kn, ae, eta_d
        self.FC = 1.0
        self.dhs_d = 1.0
        self.ncorr_d = 1.0

    def shape(self, PR, nt):
        return math.sqrt(1.0 - PR ** (-self.a)) * (1.0 + self.kn * (1.0 - nt))

    def flow(self, PR, nt, dg=0.0):
        return self.FC * self.shape(PR, nt) * (1.0 - dg / 100.0)

    def eta(self, nrel, dhs, de=0.0):
        nu = nrel * math.sqrt(self.dhs_d / dhs)
        return self.eta_d * (1.0 - self.ae * (nu - 1.0) ** 2) * (1.0 - de / 100.0)


HPT = TMap(a=4.0, kn=0.02, ae=0.80, eta_d=Spec.ETA_HPT)     # 2-stage HPT, nozzle nearly choked
PT = TMap(a=2.0, kn=0.01, ae=0.60, eta_d=Spec.ETA_PT)       # multistage PT, ellipse law


# =============================================================================
# 4. DESIGN POINT (ISO, 100 % load) -> map scaling and loss coefficients
# =============================================================================
class D:
    """design-point state (filled by run_design)"""


def _design_cycle(T3):
    S = Spec
    st = {}
    T0, P0 = ISO_T, ISO_P
    W1, T1 = S.W1, T0
    P1 = P0 - S.DP_INLET
    m, p, eta_c = CMap.raw(1.0, S.BETA_C)
    P2 = S.PR * P1
    T2, dhc, _ = compress(AIR, T1, S.PR, eta_c)
    Pc = W1 * dhc
    Wngv, Wrot = S.F_NGV * W1, S.F_ROT * W1
    Wb = W1 - Wngv - Wrot
    P3 = P2 * (1.0 - S.DP_COMB)
    far = combustor_far(T2, T3, S.ETA_B, S.LHV, S.T_FUEL)
    Wf = far * Wb
    g3 = Gas(far)
    W31 = Wb + Wf + Wngv
    g31 = Gas(Wf / (Wb + Wngv))
    T31 = mix_T([(Wb + Wf, g3, T3), (Wngv, AIR, T2)], g31, T3 - 50.0)
    dhh = Pc / (S.ETA_MGG * W31)
    dhsh = dhh / S.ETA_HPT
    T33s = g31.T_from_h(g31.h(T31) - dhsh, T31 - dhsh / 1.25)
    PRh = math.exp((g31.s(T31) - g31.s(T33s)) / g31.R)
    T33 = g31.T_from_h(g31.h(T31) - dhh, T33s + 30.0)
    W34 = W31 + Wrot
    g34 = Gas(Wf / W1)
    T34 = mix_T([(W31, g31, T33), (Wrot, AIR, T2)], g34, T33 - 20.0)
    P34 = P3 / PRh
    P35 = P34 * (1.0 - S.DP_ITD)
    P4 = P0 + S.DP_EXH
    PRp = P35 / P4
    T4, dhp, dhsp = expand(g34, T34, PRp, S.ETA_PT)
    power = S.ETA_MPT * W34 * dhp
    st.update(T0=T0, P0=P0, T1=T1, P1=P1, W1=W1, P2=P2, T2=T2, eta_c=eta_c, Pc=Pc, P3=P3, T3=T3,
              far=far, Wf=Wf, W31=W31, T31=T31, PRh=PRh, dhsh=dhsh, T33=T33, W34=W34, T34=T34,
              P34=P34, P35=P35, P4=P4, PRp=PRp, T4=T4, dhsp=dhsp, power=power, Wb=Wb,
              f34=Wf / W1, f31=Wf / (Wb + Wngv), eta_h=S.ETA_HPT, eta_p=S.ETA_PT)
    return st


def run_design():
    S = Spec
    # secant on TIT for the specified shaft power
    a, b = 1400.0, 1550.0
    fa = _design_cycle(a)['power'] - S.POWER
    fb = _design_cycle(b)['power'] - S.POWER
    for _ in range(60):
        c = b - fb * (b - a) / (fb - fa)
        a, fa = b, fb
        b, fb = c, _design_cycle(c)['power'] - S.POWER
        if abs(fb) < 1e-13 * S.POWER:
            break
    st = _design_cycle(b)
    for k, v in st.items():
        setattr(D, k, v)
    # ---- scaling of the maps and loss coefficients
    wc1 = st['W1'] * math.sqrt(st['T1'] / ISO_T) / (st['P1'] / ISO_P)
    m, p, eta = CMap.raw(1.0, S.BETA_C)
    CMap.m_scale = wc1 / m
    CMap.p_scale = (S.PR - 1.0) / (p - 1.0)
    D.wc1 = wc1
    D.k_in = S.DP_INLET / st['P1'] / wc1 ** 2                     # dP/P1 = k wc1^2
    wc2 = st['Wb'] * math.sqrt(st['T2'] / ISO_T) / (st['P2'] / ISO_P)
    D.k_b = S.DP_COMB / wc2 ** 2                                    # dP/P2 = k wc2^2
    wc34 = st['W34'] * math.sqrt(st['T34'] / ISO_T) / (st['P34'] / ISO_P)
    D.k_itd = S.DP_ITD / wc34 ** 2                                  # dP/P34 = k wc34^2
    wc4 = st['W34'] * math.sqrt(st['T4'] / ISO_T) / (st['P4'] / ISO_P)
    D.k_ex = S.DP_EXH / st['P4'] / wc4 ** 2                         # (P4-P0)/P4 = k wc4^2
    HPT.FC = st['W31'] * math.sqrt(st['T31']) / st['P3'] / HPT.shape(st['PRh'], 1.0)
    HPT.dhs_d = st['dhsh']
    HPT.ncorr_d = S.N1 / math.sqrt(st['T31'])
    PT.FC = st['W34'] * math.sqrt(st['T34']) / st['P35'] / PT.shape(st['PRp'], 1.0)
    PT.dhs_d = st['dhsp']
    PT.ncorr_d = S.N2 / math.sqrt(st['T34'])
    D.x0 = [1.0, S.BETA_C, 1.0, 1.0, 1.0]
    return st


# =============================================================================
# 5. OFF-DESIGN MATCHING
# =============================================================================
HEALTH_KEYS = ('D_GC', 'D_EC', 'D_GT', 'D_ET', 'D_GP', 'D_EP')
NX = 5


def evaluate(x, cond, full=False):
    """x = [N1/N1d, beta, TIT/TITd, PR_HPT/PR_HPTd, PR_PT/PR_PTd];
    cond = (T0 [K], P0 [kPa], shaft power [kW], health dict).  Returns residuals (and state)."""
    S = Spec
    nN, beta, t3, ph, pp = x
    T0, P0, Pt, H = cond
    N1 = nN * S.N1
    T1 = T0
    ncorr = nN / math.sqrt(T1 / ISO_T)
    wc1, PR, eta_c, vigv = CMap.evaluate(ncorr, beta, H['D_GC'], H['D_EC'])
    P1 = P0 / (1.0 + D.k_in * wc1 * wc1)
    W1 = wc1 * (P1 / ISO_P) / math.sqrt(T1 / ISO_T)
    P2 = PR * P1
    T2, dhc, _ = compress(AIR, T1, PR, eta_c)
    Pc = W1 * dhc
    Wngv, Wrot = S.F_NGV * W1, S.F_ROT * W1
    Wb = W1 - Wngv - Wrot
    wc2 = Wb * math.sqrt(T2 / ISO_T) / (P2 / ISO_P)
    P3 = P2 * (1.0 - D.k_b * wc2 * wc2)
    T3 = t3 * D.T3
    far = combustor_far(T2, T3, S.ETA_B, S.LHV, S.T_FUEL)
    Wf = far * Wb
    g3 = Gas(far)
    W31 = Wb + Wf + Wngv
    g31 = Gas(Wf / (Wb + Wngv))
    T31 = mix_T([(Wb + Wf, g3, T3), (Wngv, AIR, T2)], g31, T3 - 50.0)
    # HP turbine
    PRh = ph * D.PRh
    T33, dhh, dhsh, eta_h = expand_fn(g31, T31, PRh, lambda dhs: HPT.eta(nN, dhs, H['D_ET']))
    nth = N1 / math.sqrt(T31) / HPT.ncorr_d
    r1 = W31 * math.sqrt(T31) / P3 / HPT.flow(PRh, nth, H['D_GT']) - 1.0
    r2 = (S.ETA_MGG * W31 * dhh - Pc) / Pc
    W34 = W31 + Wrot
    g34 = Gas(Wf / W1)
    T34 = mix_T([(W31, g31, T33), (Wrot, AIR, T2)], g34, T33 - 20.0)
    P34 = P3 / PRh
    wc34 = W34 * math.sqrt(T34 / ISO_T) / (P34 / ISO_P)
    P35 = P34 * (1.0 - D.k_itd * wc34 * wc34)
    # power turbine, speed from the cubic load law
    N2 = S.N2 * (Pt / S.POWER) ** (1.0 / 3.0)
    n2rel = N2 / S.N2
    PRp = pp * D.PRp
    T4, dhp, dhsp, eta_p = expand_fn(g34, T34, PRp, lambda dhs: PT.eta(n2rel, dhs, H['D_EP']))
    ntp = N2 / math.sqrt(T34) / PT.ncorr_d
    r3 = W34 * math.sqrt(T34) / P35 / PT.flow(PRp, ntp, H['D_GP']) - 1.0
    P4 = P35 / PRp
    wc4 = W34 * math.sqrt(T4 / ISO_T) / (P4 / ISO_P)
    r4 = (P4 - P0 - D.k_ex * wc4 * wc4 * P4) / P0
    Ppt = S.ETA_MPT * W34 * dhp
    r5 = (Ppt - Pt) / Pt
    res = [r1, r2, r3, r4, r5]
    if not full:
        return res
    st = dict(T0=T0, P0=P0, T1=T1, P1=P1, N1=N1, N2=N2, ncorr=ncorr, beta=beta, wc1=wc1, W1=W1,
              PR=PR, eta_c=eta_c, vigv=vigv, P2=P2, T2=T2, Pc=Pc, P3=P3, T3=T3, far=far, Wf=Wf,
              W31=W31, T31=T31, PRh=PRh, eta_h=eta_h, T33=T33, W34=W34, T34=T34, P34=P34,
              P35=P35, PRp=PRp, eta_p=eta_p, T4=T4, P4=P4, power=Ppt,
              SM=CMap.surge_margin(wc1, PR, H['D_GC']),
              heat_rate=3600.0 * Wf * S.LHV / Ppt, eta_th=Ppt / (Wf * S.LHV),
              nu_h=nN * math.sqrt(HPT.dhs_d / dhsh), nu_p=n2rel * math.sqrt(PT.dhs_d / dhsp))
    return res, st


def _solve_lin(A, b):
    n = len(b)
    M = [row[:] + [b[i]] for i, row in enumerate(A)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(M[r][c]))
        if abs(M[p][c]) < 1e-300:
            raise ZeroDivisionError('singular Jacobian')
        M[c], M[p] = M[p], M[c]
        for r in range(c + 1, n):
            fct = M[r][c] / M[c][c]
            if fct:
                for k in range(c, n + 1):
                    M[r][k] -= fct * M[c][k]
    x = [0.0] * n
    for r in range(n - 1, -1, -1):
        x[r] = (M[r][n] - sum(M[r][k] * x[k] for k in range(r + 1, n))) / M[r][r]
    return x


def _norm(r):
    return max(abs(v) for v in r)


class SolveError(Exception):
    pass


X_LO = [0.3, 0.0, 0.3, 1.0005 / 4.0, 1.0005 / 3.5]   # hard bounds on the unknowns
X_HI = [1.3, 1.0, 1.4, 2.0, 2.0]
MAXSTEP = [0.05, 0.15, 0.05, 0.10, 0.10]


def _safe_eval(x, cond):
    try:
        r = evaluate(x, cond)
        if any(v != v for v in r):
            return None
        return r
    except (ValueError, ZeroDivisionError, OverflowError):
        return None


def newton(cond, x0, tol=1e-12, maxit=40):
    """Newton with forward-difference Jacobian, step limiting and backtracking."""
    x = list(x0)
    r = _safe_eval(x, cond)
    if r is None:
        raise SolveError('bad start')
    nr = _norm(r)
    for it in range(maxit):
        if nr < tol:
            return x, nr, it
        J = [[0.0] * NX for _ in range(NX)]
        for j in range(NX):
            h = 1e-7 * max(1.0, abs(x[j]))
            xp = list(x)
            xp[j] += h
            rp = _safe_eval(xp, cond)
            if rp is None:
                xp[j] = x[j] - h
                rp = _safe_eval(xp, cond)
                if rp is None:
                    raise SolveError('jacobian evaluation failed')
                h = -h
            for i in range(NX):
                J[i][j] = (rp[i] - r[i]) / h
        dx = _solve_lin(J, [-v for v in r])
        lam = 1.0
        for j in range(NX):
            if abs(dx[j]) * lam > MAXSTEP[j]:
                lam = MAXSTEP[j] / abs(dx[j])
        while True:
            xn = [min(max(x[j] + lam * dx[j], X_LO[j]), X_HI[j]) for j in range(NX)]
            rn = _safe_eval(xn, cond)
            if rn is not None and _norm(rn) < (1.0 - 1e-4 * lam) * nr:
                break
            if rn is not None and nr < 1e-9 and _norm(rn) <= nr * 1.000001:
                break           # round-off floor: accept and let the tolerance test decide
            lam *= 0.5
            if lam < 1e-6:
                raise SolveError('line search failed (|r|=%.3e)' % nr)
        x, r, nr = xn, rn, _norm(rn)
    if nr < tol * 100:
        return x, nr, maxit
    raise SolveError('no convergence (|r|=%.3e)' % nr)


def solve_point(T0, P0, power, health, x_start=None, cond_start=None):
    """Continuation from a solved state (default: the design point) to the requested conditions."""
    if x_start is None:
        x_start = D.x0
        cond_start = (ISO_T, ISO_P, Spec.POWER, {k: 0.0 for k in HEALTH_KEYS})
    T0s, P0s, Ps, Hs = cond_start

    def cond_at(t):
        return (T0s + t * (T0 - T0s), P0s + t * (P0 - P0s), Ps + t * (power - Ps),
                {k: Hs[k] + t * (health[k] - Hs[k]) for k in HEALTH_KEYS})

    t, dt, x = 0.0, 1.0, list(x_start)
    nsteps = 0
    while t < 1.0:
        tn = min(1.0, t + dt)
        try:
            xn, nr, it = newton(cond_at(tn), x, tol=1e-12 if tn >= 1.0 else 1e-8)
            ok = 0.0 < xn[1] < 1.0
        except SolveError:
            ok = False
        nsteps += 1
        if ok:
            t, x = tn, xn
            dt = min(1.0, dt * 2.0)
        else:
            dt *= 0.5
            if dt < 1e-3:
                raise SolveError('continuation failed at t=%.4f for T0=%.2f P=%.0f' % (t, T0, power))
    cond = cond_at(1.0)
    res, st = evaluate(x, cond, full=True)
    st['resid'] = _norm(res)
    st['x'] = x
    st['health'] = dict(health)
    st['nsteps'] = nsteps
    return st


# =============================================================================
# 6. OPERATING POINTS, MEASURED SIGNALS, FILES
# =============================================================================
LOADS = [30.0 + 8.75 * i for i in range(9)]                     # % of design power
BASE_T = [283.0, 296.0, 271.0, 301.0, 288.0, 276.0, 293.0, 268.0, 288.15]
BASE_P = [100.9, 99.8, 102.3, 100.2, 101.6, 102.5, 99.5, 101.9, 101.325]
GRID_T = [265.0 + 5.0 * i for i in range(9)]                    # 265 ... 305 K
GRID_P = [99.5 + 3.0 * i / 8.0 for i in range(9)]               # 99.5 ... 102.5 kPa


def zero_health():
    return {k: 0.0 for k in HEALTH_KEYS}


def grid_levels():
    lv = []
    for i in range(5):                       # compressor fouling
        g = 0.8 * (i + 1)
        lv.append({'D_GC': g, 'D_EC': 0.4 * g})
    for i in range(5):                       # HPT erosion
        lv.append({'D_GT': -0.4 * (i + 1), 'D_ET': 0.6 * (i + 1)})
    for i in range(3):                       # PT wear
        lv.append({'D_GP': -0.5 * (i + 1), 'D_EP': 0.7 * (i + 1)})
    lv.append(dict(lv[2], **lv[7]))          # compressor level 2 + HPT level 7
    lv.append(dict(lv[3], **lv[11]))         # compressor level 3 + PT level 11
    lv.append(dict(lv[0], **lv[5], **lv[10]))  # first step of every family
    out = []
    for d in lv:
        h = zero_health()
        h.update({k: round(v, 10) for k, v in d.items()})
        out.append(h)
    return out


def grid_days(level):
    r = random.Random(1000 + level)
    T = GRID_T[:]
    P = GRID_P[:]
    r.shuffle(T)
    r.shuffle(P)
    return T, P


# measured signals: (column, unit, function of state, noise kind, sigma)
SIGNALS = [
    ('AMB_T_C', 'degC', lambda s: s['T0'] - 273.15, 'abs', 0.5),
    ('AMB_P_BARA', 'bar a', lambda s: s['P0'] / 100.0, 'rel', 0.0005),
    ('CIT_C', 'degC', lambda s: s['T1'] - 273.15, 'abs', 0.5),
    ('CIP_BARA', 'bar a', lambda s: s['P1'] / 100.0, 'rel', 0.0005),
    ('NGG_RPM', 'rpm', lambda s: s['N1'], 'rel', 0.0002),
    ('NPT_RPM', 'rpm', lambda s: s['N2'], 'rel', 0.0002),
    ('FUEL_KGH', 'kg/h', lambda s: s['Wf'] * 3600.0, 'rel', 0.003),
    ('CDP_BARA', 'bar a', lambda s: s['P2'] / 100.0, 'rel', 0.001),
    ('CDT_C', 'degC', lambda s: s['T2'] - 273.15, 'abs', 1.5),
    ('P34_BARA', 'bar a', lambda s: s['P34'] / 100.0, 'rel', 0.001),
    ('T34_C', 'degC', lambda s: s['T34'] - 273.15, 'abs', 1.5),
    ('EXP_BARA', 'bar a', lambda s: s['P4'] / 100.0, 'rel', 0.001),
    ('EGT_C', 'degC', lambda s: s['T4'] - 273.15, 'abs', 1.5),
    ('PWR_MW', 'MW', lambda s: s['power'] / 1000.0, 'rel', 0.003),
]
SIG_FMT = {'degC': '%.5f', 'bar a': '%.7f', 'rpm': '%.4f', 'kg/h': '%.4f', 'MW': '%.7f'}

INTERNAL = [
    ('TIT_K', lambda s: s['T3']), ('SOT_K', lambda s: s['T31']), ('W1_KGS', lambda s: s['W1']),
    ('WC1_KGS', lambda s: s['wc1']), ('NGG_CORR_REL', lambda s: s['ncorr']), ('BETA', lambda s: s['beta']),
    ('SM_PCT', lambda s: s['SM']), ('VIGV_DEG', lambda s: s['vigv']), ('PR_C', lambda s: s['PR']),
    ('ETA_C', lambda s: s['eta_c']), ('PR_HPT', lambda s: s['PRh']), ('ETA_HPT', lambda s: s['eta_h']),
    ('PR_PT', lambda s: s['PRp']), ('ETA_PT', lambda s: s['eta_p']), ('P3_BARA', lambda s: s['P3'] / 100),
    ('P35_BARA', lambda s: s['P35'] / 100), ('FAR_COMB', lambda s: s['far']),
    ('HEAT_RATE_KJKWH', lambda s: s['heat_rate']), ('ETA_TH', lambda s: s['eta_th']),
    ('MAX_REL_RESIDUAL', lambda s: s['resid']),
]


def run_set(specs):
    """specs: list of (group, T0, P0, load%, health) -> list of (spec, state)"""
    out = []
    for g, T0, P0, L, H in specs:
        st = solve_point(T0, P0, L / 100.0 * Spec.POWER, H)
        st['group'] = g
        st['load'] = L
        out.append(st)
    return out


def _fmt_h(v):
    return ('%.4f' % v).rstrip('0').rstrip('.') if v != 0 else '0'


def write_csv(path, states, noisy, rng=None):
    cols = ['group'] + [s[0] for s in SIGNALS] + ['true_' + k for k in HEALTH_KEYS]
    lines = [','.join(cols)]
    for st in states:
        vals = [st['group']]
        for name, unit, fn, kind, sig in SIGNALS:
            v = fn(st)
            if noisy:
                e = rng.gauss(0.0, 1.0)
                v = v + sig * e if kind == 'abs' else v * (1.0 + sig * e)
            vals.append(SIG_FMT[unit] % v)
        vals += [_fmt_h(st['health'][k]) for k in HEALTH_KEYS]
        lines.append(','.join(vals))
    with open(path, 'w') as f:
        f.write('\n'.join(lines) + '\n')


def write_internal(path, states):
    cols = ['group', 'LOAD_PCT_SETPOINT'] + [c for c, _ in INTERNAL]
    lines = [','.join(cols)]
    for st in states:
        lines.append(','.join([st['group'], '%.4f' % st['load']] + ['%.9g' % fn(st) for _, fn in INTERNAL]))
    with open(path, 'w') as f:
        f.write('\n'.join(lines) + '\n')


# =============================================================================
# 7. CHECKS
# =============================================================================
DSIG = [('NGG_RPM', lambda s: s['N1'], 'rpm'), ('FUEL_KGH', lambda s: s['Wf'] * 3600, 'kg/h'),
        ('CDP_BARA', lambda s: s['P2'] / 100, 'bar'), ('CDT_K', lambda s: s['T2'], 'K'),
        ('P34_BARA', lambda s: s['P34'] / 100, 'bar'), ('T34_K', lambda s: s['T34'], 'K'),
        ('EGT_K', lambda s: s['T4'], 'K'), ('TIT_K', lambda s: s['T3'], 'K'), ('W1_KGS', lambda s: s['W1'], 'kg/s')]


def run_checks(log):
    res = {}
    log('== thermodynamics ==')
    log('air cp(300 K) = %.4f kJ/kg/K, cp(1000 K) = %.4f, cp(1500 K) = %.4f' %
        (AIR.cp(300.0), AIR.cp(1000.0), AIR.cp(1500.0)))
    for sp in ('N2', 'O2', 'AR', 'CO2', 'H2O', 'CH4'):
        log('  %-4s cp [J/mol/K] 300 K %.3f, 1000 K %.3f (low) / %.3f (high), 2000 K %.3f; high-range constant '
            'shift for continuity at 1000 K: h %+.4f J/mol, s %+.1e J/mol/K' % (
                sp, RU * nasa_cp(sp, 300.0), RU * nasa_cp_R(NASA7[sp][0], 1000.0), RU * nasa_cp_R(NASA7[sp][1], 1000.0),
                RU * nasa_cp(sp, 2000.0), NASA_SHIFT[sp][0], NASA_SHIFT[sp][1]))
    g = Gas(0.02)
    log('products f=0.02: cp(1000 K) = %.4f, R = %.5f kJ/kg/K (air R = %.5f)' % (g.cp(1000.0), g.R, AIR.R))
    log('LHV of CH4 from the NASA formation enthalpies = %.1f kJ/kg (model uses %.1f)' % (lhv_from_nasa(), Spec.LHV))
    r0 = evaluate(D.x0, (ISO_T, ISO_P, Spec.POWER, zero_health()))
    log('off-design residuals at the design point: %.2e' % _norm(r0))
    eb = []
    for T0, L in ((253.15, 30.0), (288.15, 100.0), (313.15, 65.0)):
        st = solve_point(T0, 101.0, L / 100 * Spec.POWER, grid_levels()[13])
        # energy in = energy out (+ mechanical losses, removed as heat)
        ein = st['W1'] * AIR.h(T0) + st['Wf'] * (Spec.ETA_B * Spec.LHV + FUEL.h(Spec.T_FUEL))
        pt_aero = st['power'] / Spec.ETA_MPT
        loss = st['Pc'] * (1 / Spec.ETA_MGG - 1) + pt_aero - st['power']
        eout = st['W34'] * Gas(st['Wf'] / st['W1']).h(st['T4']) + st['power'] + loss
        eb.append(abs(ein - eout) / (st['Wf'] * Spec.LHV))
    log('overall energy balance (degraded level 13, 3 points): max |in - out| / fuel heat = %.1e' % max(eb))
    res['energy'] = max(eb)

    log('\n== robustness sweep: T0 253..313 K x P0 {99.5, 102.5} kPa x load 30..100 %, healthy ==')
    worst = dict(resid=0.0, TIT=0.0, SMmin=1e9, bmin=1.0, bmax=0.0)
    nfail, npts = 0, 0
    hot_tit = []
    for T0 in [253.15 + 10.0 * i for i in range(7)]:
        for P0 in (99.5, 102.5):
            for L in [30.0 + 10.0 * i for i in range(8)]:
                npts += 1
                try:
                    st = solve_point(T0, P0, L / 100 * Spec.POWER, zero_health())
                except SolveError as e:
                    nfail += 1
                    log('FAIL T0=%.2f P0=%.1f L=%.0f: %s' % (T0, P0, L, e))
                    continue
                worst['resid'] = max(worst['resid'], st['resid'])
                worst['TIT'] = max(worst['TIT'], st['T3'])
                worst['SMmin'] = min(worst['SMmin'], st['SM'])
                worst['bmin'] = min(worst['bmin'], st['beta'])
                worst['bmax'] = max(worst['bmax'], st['beta'])
                if L == 100.0 and P0 == 99.5:
                    hot_tit.append((T0, st['T3']))
    log('%d points, %d failures; max residual %.1e; max TIT %.1f K; min SM %.1f %%; beta %.3f..%.3f' %
        (npts, nfail, worst['resid'], worst['TIT'], worst['SMmin'], worst['bmin'], worst['bmax']))
    log('TIT at 100 % load (P0=99.5 kPa): ' + ', '.join('%.0f K: %.0f K' % t for t in hot_tit))
    res['sweep'] = dict(worst, npts=npts, nfail=nfail, hot_tit=hot_tit)

    log('\n== robustness sweep with every grid health level at 253/313 K, 30/100 % ==')
    w2 = dict(resid=0.0, TIT=0.0, SMmin=1e9)
    nf2 = 0
    for H in grid_levels():
        for T0 in (253.15, 313.15):
            for L in (30.0, 100.0):
                try:
                    st = solve_point(T0, 101.325, L / 100 * Spec.POWER, H)
                    w2['resid'] = max(w2['resid'], st['resid'])
                    w2['TIT'] = max(w2['TIT'], st['T3'])
                    w2['SMmin'] = min(w2['SMmin'], st['SM'])
                except SolveError as e:
                    nf2 += 1
                    log('FAIL %s %.2f %.0f: %s' % (H, T0, L, e))
    log('64 points, %d failures; max residual %.1e; max TIT %.1f K; min SM %.1f %%' %
        (nf2, w2['resid'], w2['TIT'], w2['SMmin']))
    res['sweep_deg'] = dict(w2, nfail=nf2)

    log('\n== trends with load at ISO (healthy), 30..100 % in 5 % steps ==')
    iso = [solve_point(ISO_T, ISO_P, L / 100 * Spec.POWER, zero_health()) for L in range(30, 101, 5)]
    mono = {}
    for name, fn, unit in DSIG:
        v = [fn(s) for s in iso]
        inc = all(b > a for a, b in zip(v, v[1:]))
        dec = all(b < a for a, b in zip(v, v[1:]))
        mono[name] = 'increasing' if inc else ('decreasing' if dec else 'NOT monotonic')
        log('%-9s %-14s %s' % (name, mono[name], ' '.join('%.4g' % x for x in v)))
    v = [s['eta_th'] for s in iso]
    log('eta_th    ' + ' '.join('%.4f' % x for x in v))
    res['mono'] = mono

    log('\n== degradation responses at ISO (signal(level) - signal(healthy)) ==')
    levels = grid_levels()
    resp = {}
    bases = {}
    for L in (100.0, 65.0, 30.0):
        base = solve_point(ISO_T, ISO_P, L / 100 * Spec.POWER, zero_health())
        bases[L] = base
        log('-- load %.0f %% --  level: ' % L + ' '.join('%9s' % n for n, _, _ in DSIG))
        for i, H in enumerate(levels):
            st = solve_point(ISO_T, ISO_P, L / 100 * Spec.POWER, H)
            d = [fn(st) - fn(base) for _, fn, _ in DSIG]
            resp[(L, i)] = d
            log('   level%02d          ' % i + ' '.join('%9.4f' % x for x in d))
    res['resp'] = resp
    names = [n for n, _, _ in DSIG]
    ok_c = all(resp[(L, 4)][names.index(k)] > 0 for L in (100.0, 65.0, 30.0)
               for k in ('FUEL_KGH', 'T34_K', 'EGT_K'))
    log('compressor fouling (level04) at fixed power raises fuel, T34, EGT at all three loads: %s' % ok_c)
    res['fouling_ok'] = ok_c

    log('\n== linearity of the health -> signal map (ISO, noise-free) ==')
    log('dev2 = |d(step 2) - 2 d(step 1)|, dev5 = |d(step 5) - 5 d(step 1)|, in units of the measurement '
        'noise sigma; rel = the same relative to |d(step k)| for signals with |d| > 3 sigma')
    sig_of = {'NGG_RPM': lambda s: 0.0002 * s['N1'], 'FUEL_KGH': lambda s: 0.003 * s['Wf'] * 3600,
              'CDP_BARA': lambda s: 0.001 * s['P2'] / 100, 'CDT_K': lambda s: 1.5,
              'P34_BARA': lambda s: 0.001 * s['P34'] / 100, 'T34_K': lambda s: 1.5, 'EGT_K': lambda s: 1.5}
    lin = []
    for fam, (i1, i2, i5) in (('compressor', (0, 1, 4)), ('HPT', (5, 6, 9)), ('PT', (10, 11, 12))):
        kmax = 5 if fam != 'PT' else 3
        for L in (100.0, 65.0, 30.0):
            base = bases[L]
            dev2 = dev5 = rel2 = rel5 = 0.0
            for j, (name, fn, unit) in enumerate(DSIG):
                if name not in sig_of:
                    continue
                sg = sig_of[name](base)
                d1, d2, d5 = resp[(L, i1)][j], resp[(L, i2)][j], resp[(L, i5)][j]
                dev2 = max(dev2, abs(d2 - 2 * d1) / sg)
                dev5 = max(dev5, abs(d5 - kmax * d1) / sg)
                if abs(d2) > 3 * sg:
                    rel2 = max(rel2, abs(d2 - 2 * d1) / abs(d2))
                if abs(d5) > 3 * sg:
                    rel5 = max(rel5, abs(d5 - kmax * d1) / abs(d5))
            lin.append((fam, L, dev2, rel2, kmax, dev5, rel5))
            log('%-10s load %5.1f %%: step2 dev %.2f sigma (rel %.1f %%); step%d dev %.2f sigma (rel %.1f %%)' %
                (fam, L, dev2, 100 * rel2, kmax, dev5, 100 * rel5))
    res['lin'] = lin
    return res


# =============================================================================
# 8. DOCUMENTS
# =============================================================================
def design_text():
    S = Spec
    W4 = D.W34
    eta_th = D.power / (D.Wf * S.LHV)
    wc_s = CMap.surge_margin(D.wc1, S.PR)
    L = []
    a = L.append
    a('# Two-shaft industrial gas turbine - vendor-style datasheet (independent model "indep_sim")')
    a('# ISO conditions: 15 degC (288.15 K), 1.01325 bar a, dry air, 0 m; natural gas = 100 % CH4')
    a('# Rating point = "100 % load" (design point of the model); generated by sim.py')
    a('')
    a('[rating_ISO_full_load]')
    a('shaft_power_MW              = %.3f' % (D.power / 1000))
    a('heat_rate_kJ_per_kWh        = %.0f   # LHV basis' % (3600 * D.Wf * S.LHV / D.power))
    a('thermal_efficiency_pct      = %.2f' % (100 * eta_th))
    a('compressor_pressure_ratio   = %.2f   # P2/P1 (total)' % S.PR)
    a('overall_pressure_ratio_P2_P0= %.2f' % (D.P2 / D.P0))
    a('inlet_air_flow_kg_s         = %.2f' % D.W1)
    a('exhaust_flow_kg_s           = %.2f' % W4)
    a('fuel_flow_kg_h              = %.1f   # LHV %.1f MJ/kg' % (D.Wf * 3600, S.LHV / 1000))
    a('gas_generator_speed_rpm     = %.0f' % S.N1)
    a('power_turbine_speed_rpm     = %.0f   # load: P = P_rated (N2/N2_rated)^3' % S.N2)
    a('turbine_inlet_temp_K        = %.1f   # combustor exit, before NGV cooling air (T3)' % D.T3)
    a('rotor_inlet_temp_SOT_K      = %.1f   # after mixing the 5 %% NGV cooling air (T31)' % D.T31)
    a('compressor_exit_temp_K      = %.1f' % D.T2)
    a('compressor_exit_press_bara  = %.4f' % (D.P2 / 100))
    a('HPT_exit_temp_T34_K         = %.1f   # after rotor-cooling mixing' % D.T34)
    a('HPT_exit_press_P34_bara     = %.4f' % (D.P34 / 100))
    a('exhaust_temp_T4_K           = %.1f' % D.T4)
    a('exhaust_press_P4_bara       = %.4f' % (D.P4 / 100))
    a('combustor_fuel_air_ratio    = %.5f' % D.far)
    a('')
    a('[components]')
    a('compressor_isentropic_eff   = %.4f   # at rating point; map peak %.3f' % (D.eta_c, CMap.eta_pk))
    a('compressor_surge_margin_pct = %.1f   # (PR_surge - PR)/PR at constant corrected flow' % wc_s)
    a('compressor_corrected_flow   = %.3f   # kg/s at the compressor face' % D.wc1)
    a('VIGV_schedule               = open (0 deg) above 93 % corrected GG speed, -20 deg at/below 70 %, C2 smootherstep')
    a('HPT_isentropic_eff          = %.3f   # total-total' % S.ETA_HPT)
    a('HPT_pressure_ratio          = %.4f' % D.PRh)
    a('PT_isentropic_eff           = %.3f   # total-total' % S.ETA_PT)
    a('PT_pressure_ratio           = %.4f' % D.PRp)
    a('GG_mechanical_eff           = %.3f' % S.ETA_MGG)
    a('PT_mechanical_eff           = %.3f' % S.ETA_MPT)
    a('combustion_eff              = %.3f' % S.ETA_B)
    a('')
    a('[pressure_losses_at_rating]')
    a('inlet_duct_kPa              = %.2f   # scales with corrected flow^2' % S.DP_INLET)
    a('combustor_dP_over_P2        = %.3f' % S.DP_COMB)
    a('inter_turbine_duct_dP_over_P= %.3f' % S.DP_ITD)
    a('exhaust_stack_kPa           = %.2f   # P4 - P_amb' % S.DP_EXH)
    a('')
    a('[cooling_air]  # fractions of compressor inlet flow, extracted at compressor discharge')
    a('HPT_NGV_cooling             = %.3f   # re-enters before the HPT rotor (does work)' % S.F_NGV)
    a('HPT_rotor_cooling           = %.3f   # re-enters at HPT exit (no HPT work)' % S.F_ROT)
    return '\n'.join(L) + '\n'


def readme_text(base_states, checks, runtime):
    S = Spec
    chk = checks
    L = []
    a = L.append
    a('# indep_sim - independent steady-state model of a two-shaft industrial gas turbine')
    a('')
    a('Pure Python 3 (standard library only).  `python3 sim.py` regenerates every file here, deterministically '
      '(last run: %.0f s).  Written from textbook performance physics (Saravanamuttoo / Walsh & Fletcher), '
      'independent of any other engine model, to produce blind test data.' % runtime)
    a('')
    a('## Files')
    a('| file | content |')
    a('|---|---|')
    a('| `sim.py` | the simulator (thermo, maps, design point, Newton matching, file writers, checks) |')
    a('| `baseline_exact.csv`, `baseline_noisy.csv` | healthy engine, 9 loads, 9 different days |')
    a('| `grid_exact.csv`, `grid_noisy.csv` | 16 degradation levels x 9 loads (144 rows), other days |')
    a('| `prewash_exact.csv`, `prewash_noisy.csv` | the baseline loads just before an offline compressor wash (days 3 K warmer, D_GC 2.0, D_EC 0.8; group `before_wash`; added after the blind files, own noise stream) |')
    a('| `baseline_internal.csv`, `grid_internal.csv` | NOT measured: internal states of the same rows (TIT, beta, SM, efficiencies...) for diagnosis only |')
    a('| `design.txt` | datasheet at ISO full load |')
    a('| `checks.txt` | output of the self-checks (robustness sweep, trends, degradation signs, linearity) |')
    a('')
    a('## Columns of the CSV files (plant units)')
    a('| column | meaning | unit | noise 1 sigma (noisy file) |')
    a('|---|---|---|---|')
    desc = {
        'AMB_T_C': 'ambient temperature', 'AMB_P_BARA': 'barometric pressure',
        'CIT_C': 'compressor inlet total temperature T1 (= ambient, no inlet heating)',
        'CIP_BARA': 'compressor inlet total pressure P1 (after inlet duct loss)',
        'NGG_RPM': 'gas-generator speed N1', 'NPT_RPM': 'power-turbine speed N2',
        'FUEL_KGH': 'fuel (CH4) mass flow', 'CDP_BARA': 'compressor discharge total pressure P2',
        'CDT_C': 'compressor discharge total temperature T2',
        'P34_BARA': 'HPT exit total pressure P34 (HPT exit plane, after rotor-cooling mixing, BEFORE the inter-turbine duct loss)',
        'T34_C': 'HPT exit total temperature T34 (same plane: mixed with the 3 % rotor cooling air)',
        'EXP_BARA': 'PT exit (exhaust collector) total pressure P4 = P_amb + stack loss',
        'EGT_C': 'PT exhaust total temperature T4', 'PWR_MW': 'PT shaft power (at the coupling)'}
    for name, unit, fn, kind, sig in SIGNALS:
        ns = ('%.1f K' % sig) if kind == 'abs' else ('%.2f %%' % (100 * sig))
        a('| `%s` | %s | %s | %s |' % (name, desc[name], unit, ns))
    a('| `group` | `baseline` or `level00`..`level15` | - | - |')
    a('| `true_D_GC` ... `true_D_EP` | true health parameters | % | - |')
    a('')
    a('Noise: a single `random.Random(2026)` stream, first through `baseline_noisy.csv` then `grid_noisy.csv`, '
      'one `gauss(0,1)` draw per signal cell in row order, column order as above; relative noise multiplies (1 + sigma*e), absolute noise adds sigma*e (K). '
      'Exact files are printed with 5-7 decimals (far below the noise).')
    a('')
    a('Health convention (percent, positive = degraded): compressor corrected flow at given (speed, beta) '
      'x (1 - D_GC/100), efficiency x (1 - D_EC/100); HPT flow capacity x (1 - D_GT/100), efficiency '
      'x (1 - D_ET/100); PT likewise with D_GP, D_EP.  Erosion (more flow capacity) = negative D_GT/D_GP.')
    a('')
    a('## Operating points')
    a('* baseline: loads %s %% of %.1f MW; days (T_amb K / P_amb kPa): %s.' % (
        ', '.join('%g' % x for x in LOADS), S.POWER / 1000,
        ', '.join('%g/%g' % (t, p) for t, p in zip(BASE_T, BASE_P))))
    a('* grid: levels 0-4 compressor fouling D_GC = 0.8..4.0, D_EC = 0.4 D_GC; 5-9 HPT erosion '
      'D_GT = -0.4..-2.0, D_ET = 0.6..3.0; 10-12 PT wear D_GP = -0.5, -1.0, -1.5, D_EP = 0.7, 1.4, 2.1; '
      '13 = level 2 + level 7; 14 = level 3 + level 11; 15 = the FIRST step of every family together '
      '(levels 0 + 5 + 10: D_GC 0.8, D_EC 0.32, D_GT -0.4, D_ET 0.6, D_GP -0.5, D_EP 0.7) - this is how '
      '"all three at their level-1 values" was interpreted; the true_* columns are authoritative.  '
      'For each level the 9 loads run on 9 days: T_amb = 265, 270 .. 305 K and P_amb = 99.5 .. 102.5 kPa, '
      'each list shuffled with random.Random(1000 + level).')
    a('* PT speed from the load law N2 = %.0f rpm x (P/P_rated)^(1/3) in every row.' % S.N2)
    a('')
    a('## ISO full-load figures (healthy)')
    eta_th = D.power / (D.Wf * S.LHV)
    a('| quantity | value |')
    a('|---|---|')
    rows = [('shaft power', '%.3f MW' % (D.power / 1000)), ('compressor PR P2/P1', '%.2f' % S.PR),
            ('inlet air flow W1', '%.2f kg/s (corrected at face %.2f)' % (D.W1, D.wc1)),
            ('exhaust flow', '%.2f kg/s' % D.W34), ('fuel flow', '%.1f kg/h (FAR %.5f)' % (D.Wf * 3600, D.far)),
            ('TIT (combustor exit T3)', '%.1f K (%.1f degC)' % (D.T3, D.T3 - 273.15)),
            ('SOT (HPT rotor inlet T31)', '%.1f K' % D.T31),
            ('T2 / P2', '%.1f K / %.3f bar a' % (D.T2, D.P2 / 100)),
            ('T34 / P34', '%.1f K / %.3f bar a' % (D.T34, D.P34 / 100)),
            ('T4 / P4', '%.1f K / %.4f bar a' % (D.T4, D.P4 / 100)),
            ('HPT PR, PT PR', '%.3f, %.3f' % (D.PRh, D.PRp)),
            ('compressor eff, surge margin', '%.4f, %.1f %%' % (D.eta_c, CMap.surge_margin(D.wc1, S.PR))),
            ('heat rate (LHV)', '%.0f kJ/kWh' % (3600 * D.Wf * S.LHV / D.power)),
            ('thermal efficiency', '%.2f %%' % (100 * eta_th)),
            ('N1 / N2', '%.0f / %.0f rpm' % (S.N1, S.N2))]
    for k, v in rows:
        a('| %s | %s |' % (k, v))
    a('')
    a('## Baseline operating line (healthy; each load on its own day)')
    a('| load % | T_amb K | P_amb kPa | N1 rpm | N1 corr % | beta | SM % | VIGV deg | W1 kg/s | PR | TIT K | T34 K | T4 K | fuel kg/h | eff % |')
    a('|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|')
    for s in base_states:
        a('| %.2f | %.2f | %.3f | %.1f | %.2f | %.3f | %.1f | %.2f | %.2f | %.3f | %.1f | %.1f | %.1f | %.1f | %.2f |' % (
            s['load'], s['T0'], s['P0'], s['N1'], 100 * s['ncorr'], s['beta'], s['SM'], s['vigv'], s['W1'],
            s['PR'], s['T3'], s['T34'], s['T4'], s['Wf'] * 3600, 100 * s['eta_th']))
    a('')
    a('## Model')
    a('Stations: 0 ambient, 1 compressor face, 2 compressor exit, 3 combustor exit (TIT), 31 HPT rotor inlet '
      '(after NGV cooling mix), 33 HPT rotor exit, 34 HPT exit after rotor-cooling mix (measured), '
      '35 PT inlet after the inter-turbine duct, 4 PT exit (measured).')
    a('')
    a('**Thermodynamics.** Ideal-gas mixtures of N2, O2, Ar, CO2, H2O with NASA 7-coefficient polynomials '
      '(GRI-Mech 3.0 data, two ranges joined at 1000 K; the high-range integration constants are shifted by '
      '<0.01 J/mol so h and s0 are exactly continuous).  Dry air: 78.084 %% N2, 20.946 %% O2, 0.934 %% Ar, '
      '0.036 %% CO2 (M = %.3f).  Products of complete CH4 combustion, composition fixed by the fuel-air ratio '
      '(mixing of streams = mixing of air and products, tracked by W_fuel/W_air).  h(T) = sensible enthalpy from '
      '298.15 K; compressions/expansions with the entropy function: s0(T2s) = s0(T1) +/- R ln(PR), '
      'dh = dh_s / eta (compressor), dh = eta dh_s (turbines).  Air cp = %.4f kJ/kg/K at 300 K, %.4f at 1000 K.  '
      'Combustor: h_air(T2) + f (eta_b LHV + h_fuel(T_fuel)) = h_air(T3) + f dh_prod(T3), eta_b = %.3f, '
      'LHV = %.0f kJ/kg, fuel at 298.15 K (LHV implied by the NASA formation enthalpies: %.0f kJ/kg).' % (
          M_AIR, AIR.cp(300.0), AIR.cp(1000.0), S.ETA_B, S.LHV, lhv_from_nasa()))
    a('')
    c = CMap
    a('**Compressor map** (n = N1/sqrt(T1/288.15)/N1_design, beta in [0,1], 0 = surge, 1 = choke end): '
      'choke flow m_c = (1+k) n^a/(1+k n^a) with a = %.1f, k = %.1f; surge flow m_s = m_c (1 - w), '
      'w = %.2f + %.2f (1-n); surge pressure-ratio rise PR_s - 1 ~ n^%.1f; choke-end PR_c - 1 = %.2f (PR_s - 1); '
      'along a speed line an ellipse quadrant: m = m_s + (m_c - m_s) sin(pi beta/2), '
      'PR = PR_c + (PR_s - PR_c) cos(pi beta/2).  Efficiency island eta = %.3f - %.2f x^2 - %.2f x^3 - '
      '%.2f (n - %.2f)^2, x = beta - %.2f.  Flow and (PR-1) are scaled so that (n = 1, beta = %.2f) is the '
      'design point.  VIGV: s = smootherstep((0.93 - n)/0.23) in [0,1] (C2), angle = -20 s deg, '
      'corrected flow x (1 - %.2f s), efficiency - %.3f s (absolute), PR at given (n, beta) unchanged.  '
      'Health: flow x (1 - D_GC/100), efficiency x (1 - D_EC/100), PR unchanged.  '
      'Surge margin (Walsh & Fletcher): SM = (PR_surge at the same corrected flow - PR)/PR, on the '
      'VIGV-shifted and health-shifted surge line.' % (
          c.a, c.k, c.w0, c.w1, c.b, c.rc, c.eta_pk, c.ab2, c.ab3, c.an2, c.n_pk, c.b_pk, S.BETA_C,
          c.vg_flow, c.vg_eta))
    a('')
    a('**Turbines**: flow capacity W sqrt(T_in)/P_in = FC sqrt(1 - PR^-a) (1 + kn (1 - n_t)) (generalised '
      'Stodola ellipse; HPT a = %.0f -> nearly choked, PT a = %.0f -> ellipse law; kn = %.2f / %.2f; n_t = '
      'corrected speed relative to design), efficiency eta = eta_d (1 - ae (nu - 1)^2) with '
      'nu = (U/C0)/(U/C0)_d = (N/N_d) sqrt(dh_s,d/dh_s), ae = %.2f (HPT) / %.2f (PT), eta_d = %.3f / %.3f.  '
      'HPT flow capacity is defined at the rotor inlet (station 31, combustor gas + NGV cooling air).  '
      'Health: FC x (1 - D_G/100), eta x (1 - D_E/100).' % (
          HPT.a, PT.a, HPT.kn, PT.kn, HPT.ae, PT.ae, HPT.eta_d, PT.eta_d))
    a('')
    a('**Losses**: inlet dP/P1 = k wc1^2 (1.0 kPa at design); combustor dP/P2 = k wc2^2 (4 %% at design, '
      'wc2 = corrected combustor inlet flow); inter-turbine duct dP/P34 = k wc34^2 (1 %%); exhaust '
      '(P4 - P0)/P4 = k wc4^2 (3.0 kPa at design).  Cooling: %.0f %% of W1 bypasses the combustor at T2: '
      '%.0f %% mixes before the HPT rotor (enthalpy balance, does HPT work), %.0f %% mixes at HPT exit.  '
      'GG: compressor power = %.2f x HPT power.  PT shaft power = %.3f x PT aero power.' % (
          100 * (S.F_NGV + S.F_ROT), 100 * S.F_NGV, 100 * S.F_ROT, S.ETA_MGG, S.ETA_MPT))
    a('')
    a('**Matching**: unknowns N1, beta, TIT, PR_HPT, PR_PT; residuals: HPT flow capacity, GG power balance, '
      'PT flow capacity, exhaust pressure (P4 = P0 + stack loss), PT shaft power = demanded power.  N2 is '
      'given by the cubic load law.  Newton with forward-difference Jacobian, Gaussian elimination, per-variable '
      'step limits and backtracking; every point is reached by continuation from the ISO design point in '
      '(T0, P0, power, health) with adaptive step halving.  Convergence: max |relative residual| < 1e-12 '
      '(required: 1e-9).')
    a('')
    a('## Checks (details in checks.txt)')
    a('* Overall energy balance (air + fuel heat = exhaust enthalpy + shaft power + mechanical losses) closes '
      'to %.0e of the fuel heat.' % chk['energy'])
    sw = chk['sweep']
    a('* Robustness: %d healthy points T0 = 253..313 K, P0 = 99.5/102.5 kPa, load 30..100 %%: %d failures, '
      'max residual %.1e, max TIT %.0f K, min SM %.1f %%, beta %.2f..%.2f.  All grid health levels at '
      '253/313 K, 30/100 %%: %d failures, max residual %.1e, max TIT %.0f K, min SM %.1f %%.' % (
          sw['npts'], sw['nfail'], sw['resid'], sw['TIT'], sw['SMmin'], sw['bmin'], sw['bmax'],
          chk['sweep_deg']['nfail'], chk['sweep_deg']['resid'], chk['sweep_deg']['TIT'], chk['sweep_deg']['SMmin']))
    a('* TIT at 100 % load vs ambient (P0 99.5 kPa): ' + ', '.join('%.0f K -> %.0f K' % t for t in sw['hot_tit']) +
      '.  The hottest day stays below 1650 K, so no load reduction was needed.')
    a('* Trends with load at ISO (fixed day): ' + ', '.join('%s %s' % (k, v) for k, v in chk['mono'].items()) + '.')
    bm = []
    for name, fn in (('N1', lambda s: s['N1']), ('N1 corrected', lambda s: s['ncorr']), ('fuel', lambda s: s['Wf']),
                     ('P2', lambda s: s['P2']), ('T2', lambda s: s['T2']), ('T34', lambda s: s['T34']),
                     ('T4', lambda s: s['T4']), ('TIT', lambda s: s['T3'])):
        v = [fn(s) for s in base_states]
        bm.append('%s %s' % (name, 'increasing' if all(b > a for a, b in zip(v, v[1:])) else 'not monotonic'))
    a('* In the baseline file itself (each load on a different day): ' + ', '.join(bm) +
      ' - the non-monotonic physical signals are the ambient-temperature effect (e.g. 47.5 % load on a '
      '271 K day needs a lower physical N1 and T34 than 38.75 % on a 296 K day).')
    a('* Compressor fouling (level 4) at fixed power raises fuel flow, T34 and T4 at 30/65/100 %% load: %s.' %
      chk['fouling_ok'])
    a('* Linearity (ISO, noise-free; worst measured signal; deviation of the response at step 2 from twice '
      'the step-1 response, and of the largest step from k x step 1, in noise sigmas and relative): ' + '; '.join(
        '%s %.0f%%: %.2f sigma / %.1f %%, step%d %.2f sigma / %.1f %%' % (f, L, d2, 100 * r2, k, d5, 100 * r5)
        for f, L, d2, r2, k, d5, r5 in chk['lin']) + '.')
    a('')
    a('## Compromises / notes')
    a('* The NASA polynomials are used as printed (GRI-Mech 3.0); only the high-range constants were shifted '
      'for exact continuity at 1000 K.  cp is continuous there; its slope has a tiny kink.')
    a('* T34/P34 are taken at the HPT exit plane after the rotor-cooling air has mixed in and before the 1 % '
      'inter-turbine-duct loss; T4/P4 are PT-exit totals (P4 = P_amb + stack loss).  TIT is the combustor exit '
      'temperature (before the NGV cooling air); the HPT flow capacity refers to the mixed rotor inlet.')
    a('* Grid level 15 ("all three at their level-1 values") was taken as the first step of each family '
      '(levels 0 + 5 + 10).')
    a('* The 100 %% load was run on every day, including the hottest (305 K in the grid, 313 K in the '
      'robustness sweep): TIT stays <= %.0f K with degradation, so no hot-day load reduction was applied.' %
      chk['sweep_deg']['TIT'])
    a('* The operating line sits at almost constant beta (0.46-0.57); the VIGV closes below 93 % corrected '
      'speed (about -14 deg at 30 % load on a 283 K day), which keeps the surge margin at 18-27 %.')
    a('* The model LHV is the specified 50.0 MJ/kg; the NASA formation enthalpies would imply 50.03 MJ/kg.')
    a('* Compressor efficiency at the design point is %.4f (map peak %.3f at n = %.2f, beta = %.2f).' % (
        D.eta_c, CMap.eta_pk, CMap.n_pk, CMap.b_pk))
    a('* Turbine efficiencies depend only on U/C0 (no separate Reynolds or loading term); flow capacities only '
      'weakly on speed.')
    a('* Combustion efficiency is applied to the heat release only; the product composition assumes complete '
      'combustion.  Dry air, no inlet/exhaust heat losses, no customer bleed, no accessory load.')
    a('* The internal CSVs contain unmeasured truth (TIT, beta, etc.) and should not be given to a blind test.')
    return '\n'.join(L) + '\n'


def main():
    t0 = time.time()
    run_design()
    # baseline
    bspec = [('baseline', T, P, L, zero_health()) for L, T, P in zip(LOADS, BASE_T, BASE_P)]
    base = run_set(bspec)
    gspec = []
    for i, H in enumerate(grid_levels()):
        Ts, Ps = grid_days(i)
        for L, T, P in zip(LOADS, Ts, Ps):
            gspec.append(('level%02d' % i, T, P, L, H))
    grid = run_set(gspec)
    rng = random.Random(2026)          # one noise stream: baseline rows first, then grid rows
    for name, states in (('baseline', base), ('grid', grid)):
        write_csv(os.path.join(HERE, name + '_exact.csv'), states, noisy=False)
        write_csv(os.path.join(HERE, name + '_noisy.csv'), states, noisy=True, rng=rng)
        write_internal(os.path.join(HERE, name + '_internal.csv'), states)
    # Rows from before an offline compressor wash (added after the blind files; its own noise
    # stream, so the files above are unchanged): the baseline's loads on days 3 K warmer, the
    # compressor fouled D_GC 2.0, D_EC 0.8 (what the wash then removed).
    pspec = [('before_wash', T + 3.0, P, L, dict(zero_health(), D_GC=2.0, D_EC=0.8))
             for L, T, P in zip(LOADS, BASE_T, BASE_P)]
    pre = run_set(pspec)
    write_csv(os.path.join(HERE, 'prewash_exact.csv'), pre, noisy=False)
    write_csv(os.path.join(HERE, 'prewash_noisy.csv'), pre, noisy=True, rng=random.Random(2027))
    maxres = max(s['resid'] for s in base + grid + pre)
    print('solved %d points, max relative residual %.2e, TIT max %.1f K, SM min %.1f %%' % (
        len(base) + len(grid), maxres, max(s['T3'] for s in base + grid), min(s['SM'] for s in base + grid)))
    with open(os.path.join(HERE, 'design.txt'), 'w') as f:
        f.write(design_text())
    lines = []

    def log(s):
        lines.append(s)
    checks = run_checks(log)
    with open(os.path.join(HERE, 'checks.txt'), 'w') as f:
        f.write('\n'.join(lines) + '\n')
    runtime = time.time() - t0
    with open(os.path.join(HERE, 'README.md'), 'w') as f:
        f.write(readme_text(base, checks, runtime))
    print('\n'.join(lines[:12]))
    print('done in %.1f s' % runtime)


if __name__ == '__main__':
    main()
