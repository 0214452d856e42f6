"""Scratch sets of this simulator for measurements, not for the blind files: written to a
directory given on the command line (default ./indep30_extra), never into this folder.

    python3 extra_sets.py DIR

writes, from sim.py's own engine and noise model:
  healthy_days_{exact,noisy}.csv  the healthy engine on the grid's days (16 groups h00..h15, the
                                  loads and days of grid levels 0..15), noise seed 77
  baseline_exact.csv              the baseline without noise (as baseline_exact.csv here)
  baseline_seed{1..8}.csv         the baseline with other draws of its noise (seeds 1..8)
  level06_draws.csv               grid level 6 (HP-turbine erosion) with 24 draws of the noise
                                  (groups mc00..mc23, seeds 500..523)
  level06_t1_draws.csv            the same with noise on T1 and the ambient temperature only
Written by gtwatch's developers beside the simulator's author's files; it only calls sim.py.
"""
import os
import random
import sys

import sim


def draws(states, path, seeds, only=None):
    """Writes `states` once per seed (group mcNN), noise on every column, or on `only`."""
    signals = list(sim.SIGNALS)
    if only is not None:
        sim.SIGNALS = [(n, u, f, k, s if n in only else 0.0) for (n, u, f, k, s) in signals]
    out = []
    tmp = path + '.tmp'
    try:
        for k, seed in enumerate(seeds):
            for st in states:
                st['group'] = 'mc%02d' % k
            sim.write_csv(tmp, states, noisy=True, rng=random.Random(seed))
            rows = open(tmp).read().splitlines()
            if not out:
                out.append(rows[0])
            out += rows[1:]
    finally:
        sim.SIGNALS = signals
        if os.path.exists(tmp):
            os.remove(tmp)
    with open(path, 'w') as f:
        f.write('\n'.join(out) + '\n')


def main():
    d = sys.argv[1] if len(sys.argv) > 1 else 'indep30_extra'
    os.makedirs(d, exist_ok=True)
    sim.run_design()
    healthy = []
    for i in range(16):
        ts, ps = sim.grid_days(i)
        healthy += [('h%02d' % i, t, p, load, sim.zero_health())
                    for load, t, p in zip(sim.LOADS, ts, ps)]
    st = sim.run_set(healthy)
    sim.write_csv(os.path.join(d, 'healthy_days_exact.csv'), st, noisy=False)
    sim.write_csv(os.path.join(d, 'healthy_days_noisy.csv'), st, noisy=True, rng=random.Random(77))
    base = sim.run_set([('baseline', t, p, load, sim.zero_health())
                        for load, t, p in zip(sim.LOADS, sim.BASE_T, sim.BASE_P)])
    sim.write_csv(os.path.join(d, 'baseline_exact.csv'), base, noisy=False)
    for seed in range(1, 9):
        sim.write_csv(os.path.join(d, 'baseline_seed%d.csv' % seed), base, noisy=True,
                      rng=random.Random(seed))
    ts, ps = sim.grid_days(6)
    lv6 = sim.run_set([('level06', t, p, load, sim.grid_levels()[6])
                       for load, t, p in zip(sim.LOADS, ts, ps)])
    draws(lv6, os.path.join(d, 'level06_draws.csv'), range(500, 524))
    draws(lv6, os.path.join(d, 'level06_t1_draws.csv'), range(500, 524), only={'CIT_C', 'AMB_T_C'})
    print('wrote', d)


if __name__ == '__main__':
    main()
