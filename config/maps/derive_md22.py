#!/usr/bin/env python3
"""Derive the maps of config/engine_md22.toml from the reference maps (hpc.map, hpt.map, lpt.map).

Run from anywhere: `python3 config/maps/derive_md22.py` rewrites md22_hpc.map, md22_hpt.map and
md22_pt.map next to this script (no dependencies beyond the standard library). The Rust test
`derived_maps_are_the_documented_transform_of_the_reference_maps` (tests/md22_engine.rs) applies
the same transform to the reference maps and checks every value of the committed files, so the
files and this script cannot drift apart.

The transform (SOURCES.md states it too). Speed keys (relative corrected speed, 1.0 = design) and
beta keys are kept: the derived maps have the reference maps' speed lines and beta grid.

Compressor (from hpc.map, whose design point is speed 1.0 / beta 0.5: PR 23.0, eff 0.852,
corrected flow 206.0):
  a      = ln(18.5) / ln(23.0)                   (0.9305: fewer stages at similar stage loading)
  PR'    = PR ** a                               (design PR 23.0 -> 18.5; log PR scales with a)
  Wc'    = 70.0 * (Wc / 206.0) ** a              (design corrected flow 70 kg/s; part-speed flow
                                                  shortfall milder, as in a lower-PR compressor)
  eff'   = 1 - (1 - eff) * (1 - 0.87) / (1 - 0.852)   (every loss scaled: design eff 0.87)
  Surge line: its PR and flow points take the same PR and flow transforms.

Turbines (HPT from hpt.map, PT from lpt.map; their design point is speed 1.0 / PR 5.0, i.e.
beta 0.4 between the Min/Max Pressure Ratio tables 3 and 8):
  PRmin', PRmax' = PRmin ** b, PRmax ** b        (the values stay on their beta columns, so the
                                                  old design point beta 0.4 lands at
                                                  PR' = 3**b + 0.4 (8**b - 3**b))
  b = 0.90 (HPT, design PR' 4.2119), 0.85 (PT, design PR' 3.8691)
  Wc'    = W_d * Wc / Wc(1.0, beta 0.4)          (W_d: 12.0 HPT, 40.0 PT; choked-flow shape kept)
  eff'   = 1 - (1 - eff) * (1 - eta_d) / (1 - eff(1.0, beta 0.4))
                                                 (eta_d: 0.89 HPT, 0.92 PT)
"""

import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))


def tokens(text):
    return text.split()


def read_map(path):
    """Returns (title, reynolds_line, [(name, col_keys, rows[(key, values)])])."""
    with open(path) as f:
        lines = f.read().splitlines()
    title, reynolds = lines[0], lines[1]
    tables = []
    i = 2
    while i < len(lines):
        name = lines[i].strip()
        i += 1
        if not name:
            continue
        nums = []
        # Read numbers until the table is complete (by counts, as the Rust reader does).
        while True:
            nums += [float(x) for x in tokens(lines[i])]
            i += 1
            header = nums[0]
            rows = int(header) - 1
            cols = round((header - int(header)) * 1000) - 1
            if len(nums) >= 1 + cols + rows * (cols + 1):
                break
        col_keys = nums[1 : 1 + cols]
        body = nums[1 + cols :]
        rows_out = []
        for r in range(rows):
            chunk = body[r * (cols + 1) : (r + 1) * (cols + 1)]
            rows_out.append((chunk[0], chunk[1:]))
        tables.append((name, col_keys, rows_out))
    return title, reynolds, tables


def fmt(x):
    return f"{x:12.5f}"


def write_map(path, title, reynolds, tables):
    out = [title, reynolds]
    for name, col_keys, rows in tables:
        out.append(name)
        header = len(rows) + 1 + (len(col_keys) + 1) / 1000.0
        out.append(fmt(header) + "".join(fmt(c) for c in col_keys))
        for key, values in rows:
            out.append(fmt(key) + "".join(fmt(v) for v in values))
        out.append("")
    with open(path, "w") as f:
        f.write("\n".join(out))


def table(tables, name):
    for t in tables:
        if t[0] == name:
            return t
    raise KeyError(name)


def value_at(t, speed, col):
    _, cols, rows = t
    for key, values in rows:
        if abs(key - speed) < 1e-9:
            return values[cols.index(col)]
    raise KeyError((speed, col))


def compressor():
    title, reyn, tables = read_map(os.path.join(HERE, "hpc.map"))
    wc_d = value_at(table(tables, "Mass Flow"), 1.0, 0.5)
    eff_d = 0.852
    a = math.log(18.5) / math.log(23.0)
    flow = lambda w: 70.0 * (w / wc_d) ** a
    pr = lambda p: p**a
    eff = lambda e: 1.0 - (1.0 - e) * (1.0 - 0.87) / (1.0 - eff_d)
    out = []
    for name, cols, rows in tables:
        if name == "Mass Flow":
            out.append((name, cols, [(k, [flow(v) for v in vs]) for k, vs in rows]))
        elif name == "Pressure Ratio":
            out.append((name, cols, [(k, [pr(v) for v in vs]) for k, vs in rows]))
        elif name == "Efficiency":
            out.append((name, cols, [(k, [eff(v) for v in vs]) for k, vs in rows]))
        elif name == "Surge Line":
            out.append((name, [flow(c) for c in cols], [(k, [pr(v) for v in vs]) for k, vs in rows]))
        else:
            raise ValueError(name)
    title = (
        "99    MD22 compressor map (derived from hpc.map by derive_md22.py: PR' = PR^0.9305, "
        "Wc' = 70 (Wc/206)^0.9305, losses x 0.878; design PR 18.5, efficiency 0.87 at speed 1.0, beta 0.5)"
    )
    write_map(os.path.join(HERE, "md22_hpc.map"), title, reyn, out)


def turbine(src, dst, b, w_d, eta_d, label):
    title, reyn, tables = read_map(os.path.join(HERE, src))
    wc_t = table(tables, "Mass Flow")
    beta_d = 0.4  # PR 5.0 between 3 and 8
    wc_d = value_at(wc_t, 1.0, beta_d)
    eff_src = value_at(table(tables, "Efficiency"), 1.0, beta_d)
    out = []
    for name, cols, rows in tables:
        if name in ("Min Pressure Ratio", "Max Pressure Ratio"):
            out.append((name, cols, [(k, [v**b for v in vs]) for k, vs in rows]))
        elif name == "Mass Flow":
            out.append((name, cols, [(k, [w_d * v / wc_d for v in vs]) for k, vs in rows]))
        elif name == "Efficiency":
            f = (1.0 - eta_d) / (1.0 - eff_src)
            out.append((name, cols, [(k, [1.0 - (1.0 - v) * f for v in vs]) for k, vs in rows]))
        else:
            raise ValueError(name)
    pr_d = 3.0**b + beta_d * (8.0**b - 3.0**b)
    title = (
        f"99    MD22 {label} map (derived from {src} by derive_md22.py: PR limits ^{b}, "
        f"Wc' = {w_d} Wc/Wc_d, losses scaled; design PR {pr_d:.4f}, efficiency {eta_d} at speed 1.0)"
    )
    write_map(os.path.join(HERE, dst), title, reyn, out)
    return pr_d


if __name__ == "__main__":
    compressor()
    hpt = turbine("hpt.map", "md22_hpt.map", 0.90, 12.0, 0.89, "HP turbine")
    pt = turbine("lpt.map", "md22_pt.map", 0.85, 40.0, 0.92, "power turbine")
    print(f"design PR on the derived maps: HPT {hpt:.6f}, PT {pt:.6f}")
