"""Reference values for gtwatch's fuel thermo (src/thermo/fuel.rs), computed with Cantera 3.2.0.

Writes cantera_fuel_products.csv beside this file: for each fuel, its LHV at 288.15 K and the
properties of its complete lean combustion products in dry air at several fuel-air ratios.
Species data: GRI-Mech 3.0 (gri30.yaml, shipped with Cantera) plus n-butane from JetSurF 2.0
(`jetsurf.yaml`, as shipped with GSPy; pass its path as the first argument). The products'
composition is worked out here from the element balance, independently of the Rust code.

    pip install cantera==3.2.0
    python3 tests/data/cantera_fuel_products.py path/to/jetsurf.yaml
"""
import csv
import os
import sys

import cantera as ct

T_REF = 288.15
AIR_X = {"N2": 0.78084, "O2": 0.20946, "AR": 0.00934, "CO2": 0.00036}
GAS_FUELS = {
    # name: mole fractions
    "natural_gas": {"CH4": 0.85, "C2H6": 0.07, "C3H8": 0.03, "C4H10": 0.01, "N2": 0.02,
                    "CO2": 0.015, "H2": 0.005},
    "propane": {"C3H8": 1.0},
    "hydrogen": {"H2": 1.0},
}
LIQUID_HC = {"liquid_hc1.92": 1.92}

gri = ct.Solution("gri30.yaml")
species = [gri.species(n) for n in ["N2", "O2", "AR", "CO2", "H2O", "CH4", "C2H6", "C3H8", "H2"]]
species.append(ct.Solution(sys.argv[1]).species("C4H10"))
gas = ct.Solution(thermo="ideal-gas", species=species)
W = dict(zip(gas.species_names, gas.molecular_weights))


def h_mol(name, t):
    gas.TPX = t, ct.one_atm, {name: 1.0}
    return gas.enthalpy_mole  # J/kmol, with heat of formation


def products_y(far, fuel_x=None, hc=None):
    """Mass fractions of the products per kg of air + far kg of fuel (element balance)."""
    m_air = sum(x * W[s] for s, x in AIR_X.items())
    y = {s: x * W[s] / m_air for s, x in AIR_X.items()}
    y.setdefault("H2O", 0.0)
    if fuel_x is not None:
        m_f = sum(x * W[s] for s, x in fuel_x.items())
        kmol = far / m_f  # kmol of fuel per kg air
        c = h = 0.0
        for s, x in fuel_x.items():
            comp = gas.species(s).composition
            if s in ("N2", "CO2"):
                y[s] += kmol * x * W[s]
                continue
            c += x * comp.get("C", 0.0)
            h += x * comp.get("H", 0.0)
    else:
        m_f = W_C + hc * W_H
        kmol = far / m_f
        c, h = 1.0, hc
    y["O2"] -= kmol * (c + h / 4) * W["O2"]
    y["CO2"] += kmol * c * W["CO2"]
    y["H2O"] += kmol * h / 2 * W["H2O"]
    total = sum(y.values())
    assert abs(total - (1 + far)) < 1e-12, total
    return {s: v / total for s, v in y.items()}


W_C = gas.atomic_weight("C")
W_H = gas.atomic_weight("H")
rows = []
for name, fx in list(GAS_FUELS.items()) + list(LIQUID_HC.items()):
    is_gas = isinstance(fx, dict)
    if is_gas:
        m_f = sum(x * W[s] for s, x in fx.items())
        h_react = sum(x * h_mol(s, T_REF) for s, x in fx.items())
        c = sum(x * gas.species(s).composition.get("C", 0) for s, x in fx.items() if s != "CO2")
        h = sum(x * gas.species(s).composition.get("H", 0) for s, x in fx.items())
        n2 = fx.get("N2", 0.0)
        co2 = fx.get("CO2", 0.0)
        h_prod = (c + co2) * h_mol("CO2", T_REF) + h / 2 * h_mol("H2O", T_REF) + n2 * h_mol("N2", T_REF)
        lhv = (h_react + (c + h / 4) * h_mol("O2", T_REF) - h_prod) / m_f
    else:
        lhv = float("nan")  # liquid: correlation, not a Cantera quantity
    for far in (0.01, 0.02, 0.03) if name != "hydrogen" else (0.005, 0.01, 0.02):
        y = products_y(far, fx if is_gas else None, None if is_gas else fx)
        gas.TPY = T_REF, ct.one_atm, y
        h0, s0 = gas.enthalpy_mass, gas.entropy_mass
        for t in range(300, 2201, 100):
            gas.TPY = t, ct.one_atm, y
            rows.append([name, f"{lhv:.1f}", f"{far:.3f}", f"{t:.1f}", f"{gas.cp_mass:.4f}",
                         f"{ct.gas_constant / gas.mean_molecular_weight:.5f}",
                         f"{gas.enthalpy_mass - h0:.2f}", f"{gas.entropy_mass - s0:.5f}"])

out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "cantera_fuel_products.csv")
with open(out, "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["fuel", "lhv_288_J_kg", "fuel_air_ratio", "T_K", "cp_J_kgK", "R_J_kgK",
                "h_minus_h288_J_kg", "s0_minus_s0_288_J_kgK"])
    w.writerows(rows)
print(f"wrote {len(rows)} rows to {out}")
