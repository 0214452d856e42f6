#!/usr/bin/env python3
"""
indep2 / season.py -- a season of start-ups of the indep2 unit, for trying the whole product
(replay, Method B, trends, wash detection and advice) on a unit gtwatch's code did not make.

Every start-up is dyn.py's (its engine, control, sequence, lags and noise definitions,
unchanged); this file only chooses the days, the loads and the health of each start:
  * compressor fouling growing linearly with operating days (D_GC, D_EC = 0.45 D_GC),
    an offline wash on SEASON_WASH_DAY that takes away WASH_RECOVERY of it,
  * HP-turbine erosion growing slowly and never recovered (D_GT < 0, D_ET > 0),
  * the PT untouched,
  * one start every START_EVERY_DAYS days, at 70-100 % of base load, on a seasonal ambient.
Writes, into the directory given as the first argument (default ./season):
  season_log.csv    the unit's log as a historian exports it (same columns as
                    startups/operations_log.csv): 30 min of rest before each start at 10 s,
                    the start, its hour-long run shortened to the last 300 s dyn.py logs, the
                    normal shutdown; nothing between days (the historian's gap)
  season_truth.csv  per start: time of the start command, ambient, target, true health
Python 3 standard library only; two processes.  `python3 season.py OUT [N_STARTS]`.
"""
import math
import os
import random
import sys
from datetime import datetime, timedelta, timezone
from multiprocessing import Pool

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.dont_write_bytecode = True
import dyn  # noqa: E402
from dyn import H, BASE_MW, MEAS, iso, fmt_meas, add_noise, rest_meas  # noqa: E402
from sim import HEALTH_KEYS  # noqa: E402

SEASON_T0 = datetime(2026, 3, 2, 0, 0, 0, tzinfo=timezone.utc)
START_EVERY_DAYS = 3
SEASON_WASH_DAY = 75            # offline wash between the starts either side of this day
WASH_RECOVERY = 0.9             # share of the fouling an offline wash takes away
FOUL_PER_DAY = 0.05             # D_GC points per calendar day (a peaking unit in dusty air)
EROSION_PER_DAY = 0.008         # D_GT points (negative) per day; D_ET = 1.2 x |D_GT|
REST_S = 1800                   # s of rest logged before each start
SEED = 20260302


def health_on(day):
    """True health on calendar day `day` after SEASON_T0."""
    if day < SEASON_WASH_DAY:
        gc = FOUL_PER_DAY * day
    else:
        gc = FOUL_PER_DAY * SEASON_WASH_DAY * (1.0 - WASH_RECOVERY) + FOUL_PER_DAY * (day - SEASON_WASH_DAY)
    gt = -EROSION_PER_DAY * day
    return H(D_GC=gc, D_EC=0.45 * gc, D_GT=gt, D_ET=-1.2 * gt)


def plan(n_starts):
    rng = random.Random(SEED)
    specs = []
    for i in range(n_starts):
        day = i * START_EVERY_DAYS
        # seasonal ambient: 4 degC in early March rising to 28 degC by June, +/- 4 K day to day
        tc = 4.0 + 24.0 * min(1.0, day / 100.0) + rng.uniform(-4.0, 4.0)
        pk = rng.uniform(99.6, 102.4)
        target = BASE_MW * rng.choice([0.7, 0.8, 0.9, 1.0, 1.0])
        hour = rng.choice([5, 6, 7, 8])
        specs.append((i + 1, day, hour, ('season_%03d' % (i + 1), (round(tc, 2), round(pk, 2)),
                                          target, health_on(day), 'season start')))
    return specs


def run(spec):
    seq, day, hour, s = spec
    R = dyn.simulate(s, True)
    return seq, day, hour, s, R['rec'], R['shut'], R['ev_all']


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.getcwd(), 'season')
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 40
    os.makedirs(out, exist_ok=True)
    with Pool(2) as pool:
        results = pool.map(run, plan(n))
    rng = random.Random(SEED + 1)
    rows, truth = [], []
    for seq, day, hour, s, rec, shut, ev in results:
        name, (tc, pk), target, hp, _ = s
        t0 = SEASON_T0 + timedelta(days=day, hours=hour)
        rest = rest_meas(tc + 273.15, pk * 1e3)
        ts = t0 - timedelta(seconds=REST_S)
        while ts < t0:
            rows.append(fmt_meas(iso(ts), add_noise(rest, rng), True))
            ts += timedelta(seconds=dyn.REST_DT)
        for r in rec + shut:
            rows.append(fmt_meas(iso(t0 + timedelta(seconds=int(round(r[0])))), add_noise(r[2], rng), True))
        truth.append(','.join(['%d' % seq, name, iso(t0 + timedelta(seconds=int(round(ev['start_cmd'])))),
                               iso(t0 + timedelta(seconds=int(round(ev['breaker_close'])))),
                               '%d' % day, '%.2f' % tc, '%.2f' % pk, '%.3f' % target] +
                              ['%.3f' % hp[k] for k in HEALTH_KEYS]))
        print('%s day %3d  %5.1f C  %5.2f MW  D_GC %.2f D_GT %.2f' % (name, day, tc, target, hp['D_GC'], hp['D_GT']))
    dyn.write_csv(os.path.join(out, 'season_log.csv'), ['timestamp'] + MEAS, rows)
    dyn.write_csv(os.path.join(out, 'season_truth.csv'),
                  ['seq', 'name', 'start_cmd_time', 'breaker_close_time', 'day', 'T_amb_C', 'P_amb_kPa',
                   'target_MW'] + ['true_' + k for k in HEALTH_KEYS], truth)
    print('wash between day %d and %d' % (SEASON_WASH_DAY - START_EVERY_DAYS, SEASON_WASH_DAY))


if __name__ == '__main__':
    main()
