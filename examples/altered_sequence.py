#!/usr/bin/env python3
"""A replayable log of daily start-ups on a fouling trend, with one instrument altered outside
the model from a chosen start-up on: how the README's replayed sequences were made.

Each start-up is `gtwatch simulate --noise` at its own health (compressor fouling 0.3 %/day,
D_EC 0.15, turbines wearing slowly) and seed, stamped one a day at 06:00 UTC, followed by 20
minutes at base load; the `phase` and `true_*` columns are dropped, as a plant log has neither.
The alteration is applied to the written values only, so the model never sees it:

    python3 examples/altered_sequence.py --alter power_mw:scale:0.978 --from 4 --out log.csv
    python3 examples/altered_sequence.py --alter t1_k:offset:2.5 --from 4 --out log.csv

then `gtwatch replay --config gtwatch.toml log.csv` (a copy of config/gtwatch.toml with
`[storage] path` set), `gtwatch wash advise --config gtwatch.toml` and `gtwatch history
--config gtwatch.toml`. Standard library only.
"""

import argparse
import csv
import datetime
import random
import subprocess
import tempfile
from pathlib import Path


def health_at(k: int) -> str:
    return (
        f"D_GC={0.4 + 0.3 * k:.2f},D_EC={0.2 + 0.15 * k:.2f},"
        f"D_GT={0.3 + 0.02 * k:.2f},D_ET={0.4 + 0.03 * k:.2f}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--gtwatch", default="target/release/gtwatch")
    ap.add_argument("--start-ups", type=int, default=8)
    ap.add_argument("--from", dest="first", type=int, default=4,
                    help="first altered start-up (0-based)")
    ap.add_argument("--alter", required=True,
                    help="COLUMN:scale:FACTOR or COLUMN:offset:VALUE, e.g. power_mw:scale:0.978")
    ap.add_argument("--seed", type=int, default=60, help="seed of the first start-up")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    column, how, amount = a.alter.split(":")
    amount = float(amount)
    if how not in ("scale", "offset"):
        raise SystemExit("--alter: scale or offset")
    rng = random.Random(5)
    with open(a.out, "w", newline="") as out, tempfile.TemporaryDirectory() as tmp:
        w = None
        for k in range(a.start_ups):
            path = Path(tmp) / f"s{k}.csv"
            subprocess.run(
                [a.gtwatch, "simulate", "--health", health_at(k), "--noise",
                 "--seed", str(a.seed + k), "--out", str(path)],
                check=True, capture_output=True)
            rows = list(csv.DictReader(open(path)))
            cols = [c for c in rows[0] if c not in ("time_s", "phase") and not c.startswith("true_")]
            if column not in cols:
                raise SystemExit(f"--alter: no column {column} (columns: {', '.join(cols)})")
            if w is None:
                w = csv.writer(out)
                w.writerow(["time"] + cols)
            t0 = datetime.datetime(2025, 3, 1 + k, 6, 0, 0, tzinfo=datetime.timezone.utc)

            def value(c: str, v: float) -> float:
                if c == column and k >= a.first:
                    return v * amount if how == "scale" else v + amount
                return v

            last = None
            for r in rows:
                t = t0 + datetime.timedelta(seconds=float(r["time_s"]))
                vals = [value(c, float(r[c])) for c in cols]
                w.writerow([t.strftime("%Y-%m-%dT%H:%M:%SZ")] + [f"{v:.6f}" for v in vals])
                last = (t, vals)
            # Twenty minutes more at base load, with a little noise (a held value reads stuck).
            t, vals = last
            for i in range(1, 1201):
                stamp = (t + datetime.timedelta(seconds=i)).strftime("%Y-%m-%dT%H:%M:%SZ")
                noisy = [v + rng.gauss(0.0, 0.0005 * abs(v) + 1e-3) for v in vals]
                w.writerow([stamp] + [f"{v:.6f}" for v in noisy])


if __name__ == "__main__":
    main()
