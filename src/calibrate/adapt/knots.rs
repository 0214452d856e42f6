//! Where an adaptation curve's knots go and how many the data carry: evenly spaced from each
//! end of a component's speed range towards the design anchor — below it from the lowest
//! relative speed, and above it from the highest where the data reach there (a generator's PT
//! at part load, or any component on a cold day, runs above its design corrected speed) — at
//! least [`MIN_KNOT_SPACING`] apart, one fewer than the distinct speeds the data hold.
//! Pure arithmetic on speeds; must not fit or touch an engine.

/// How far from the design anchor (relative speed) the data must reach on a side for that
/// side to get knots: nearer, the anchor pins the curves and a knot would sit on it.
pub(super) const SIDE_REACH: f64 = 0.03;

/// Least spacing of knots (relative speed): the engine file refuses a knot within 0.01 of the
/// design anchor, and [`knots`] puts the innermost one a spacing from it.
pub(super) const MIN_KNOT_SPACING: f64 = 0.015;

/// How far `range` reaches below and above the design anchor, each 0 where it does not reach
/// beyond [`SIDE_REACH`].
fn reach(range: [f64; 2]) -> [f64; 2] {
    let below = 1.0 - range[0];
    let above = range[1] - 1.0;
    [
        if below > SIDE_REACH { below } else { 0.0 },
        if above > SIDE_REACH { above } else { 0.0 },
    ]
}

/// Whether `range` reaches far enough from the design anchor on either side for a knot.
pub(super) fn has_reach(range: [f64; 2]) -> bool {
    reach(range).iter().any(|r| *r > 0.0)
}

/// The most knots that fit [`MIN_KNOT_SPACING`] apart on each side.
fn capacity(range: [f64; 2]) -> [usize; 2] {
    reach(range).map(|r| {
        if r > 0.0 {
            ((r / MIN_KNOT_SPACING).floor() as usize).max(1)
        } else {
            0
        }
    })
}

/// `count` knots over `range`: split between the sides the range reaches in proportion to
/// their reach (at least one on each when `count` allows, never more than fit a side), each
/// side's evenly spaced from its end towards the design speed (the anchor excluded);
/// increasing. One knot goes to the side that reaches further.
pub(super) fn knots(range: [f64; 2], count: usize) -> Vec<f64> {
    let [below, above] = reach(range);
    let [cap_b, cap_a] = capacity(range);
    let n_above = if above == 0.0 || count == 0 {
        0
    } else if below == 0.0 {
        count
    } else if count == 1 {
        usize::from(above > below)
    } else {
        let share = (count as f64 * above / (below + above)).round() as usize;
        share.clamp(1, count - 1)
    };
    // Respect each side's capacity (the caller never asks more than both hold together).
    let n_above = n_above.min(cap_a).max(count.saturating_sub(cap_b));
    let n_below = count - n_above;
    let lo = range[0];
    let hi = range[1];
    let mut out: Vec<f64> = (0..n_below)
        .map(|i| lo + i as f64 * (1.0 - lo) / n_below as f64)
        .collect();
    out.extend(
        (0..n_above)
            .rev()
            .map(|i| hi - i as f64 * (hi - 1.0) / n_above as f64),
    );
    out
}

/// The most knots [`knots`] can spread over `range` with [`MIN_KNOT_SPACING`] (at least 1).
pub(super) fn knots_that_fit(range: [f64; 2]) -> usize {
    capacity(range).iter().sum::<usize>().max(1)
}

/// Distinct speeds (to 0.005) further than 0.01 from the design speed in `speeds` (whose
/// range is `range`), on the sides that get knots (speeds just above the design count only
/// where the range reaches beyond [`SIDE_REACH`] there: else the curve above the anchor is its
/// fade, with no knot to carry).
pub(super) fn distinct_speeds(speeds: &[f64], range: [f64; 2]) -> usize {
    let above = reach(range)[1] > 0.0;
    let mut v: Vec<i64> = speeds
        .iter()
        .filter(|s| **s < 0.99 || (above && **s > 1.01))
        .map(|s| (s / 0.005).round() as i64)
        .collect();
    v.sort_unstable();
    v.dedup();
    v.len()
}

/// How many knots a component's data can carry, and what sets it: one fewer than its
/// `distinct` speeds away from the design speed (at least 1), at most `max`, and no more than
/// fit [`MIN_KNOT_SPACING`] apart from the ends of `range` to the anchor.
pub(super) fn knot_limit(distinct: usize, range: [f64; 2], max: usize) -> (usize, String) {
    let by_data = distinct.saturating_sub(1).max(usize::from(distinct > 0));
    let by_spacing = knots_that_fit(range);
    let n = by_data.min(max).min(by_spacing);
    let why = if n == by_data {
        format!("one fewer than the data's {distinct} distinct speeds away from the design speed")
    } else if n == max {
        format!(
            "the most a curve gets (the data's {distinct} distinct speeds away from the design \
             speed would carry {by_data})"
        )
    } else {
        format!(
            "as many as fit {MIN_KNOT_SPACING} apart between the data's speeds {:.3}…{:.3} and \
             the design anchor",
            range[0], range[1]
        )
    };
    (n, why)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knots_spread_from_the_lowest_speed_towards_design() {
        assert_eq!(knots([0.7, 1.0], 1), vec![0.7]);
        let k = knots([0.7, 1.01], 3);
        assert!((k[1] - 0.8).abs() < 1e-12 && (k[2] - 0.9).abs() < 1e-12);
    }

    #[test]
    fn knots_spread_from_the_highest_speed_where_the_data_run_above_design() {
        // A generator's PT at part load: corrected speeds from 1.02 to 1.07, all above design.
        let k = knots([1.02, 1.07], 2);
        assert!(
            (k[0] - 1.035).abs() < 1e-12 && (k[1] - 1.07).abs() < 1e-12,
            "{k:?}"
        );
        // Both sides: shared by reach, at least one each, increasing; one knot goes where the
        // data reach further.
        let k = knots([0.8, 1.1], 3);
        assert_eq!(k.len(), 3);
        assert!((k[0] - 0.8).abs() < 1e-12 && (k[1] - 0.9).abs() < 1e-12);
        assert!((k[2] - 1.1).abs() < 1e-12);
        assert_eq!(knots([0.8, 1.1], 1), vec![0.8]);
        assert_eq!(knots([0.9, 1.2], 1), vec![1.2]);
        let k = knots([0.96, 1.2], 4);
        assert!(k.windows(2).all(|w| w[1] > w[0]), "{k:?}");
        assert_eq!(k.iter().filter(|x| **x < 1.0).count(), 1, "{k:?}");
        // A side the data barely leave gets none.
        assert_eq!(
            knots([0.98, 1.1], 2).iter().filter(|x| **x < 1.0).count(),
            0
        );
        assert!(!has_reach([0.975, 1.02]));
        assert!(has_reach([0.99, 1.04]));
    }

    #[test]
    fn knots_keep_clear_of_the_design_anchor() {
        // Data from 0.95 up: 6 knots would put the last at 0.9917, which the engine file
        // refuses (within 0.01 of the anchor).
        let n = knots_that_fit([0.95, 1.0]);
        assert_eq!(n, 3);
        let k = knots([0.95, 1.0], n);
        assert!(
            k.iter().all(|x| 1.0 - x >= MIN_KNOT_SPACING - 1e-12),
            "{k:?}"
        );
        assert_eq!(knots_that_fit([0.969, 1.0]), 2);
        assert_eq!(knots_that_fit([0.99, 1.0]), 1);
        // Both sides: each side's own capacity, never a knot nearer the anchor than a spacing.
        assert_eq!(knots_that_fit([0.95, 1.05]), 6);
        for count in 1..=6 {
            let k = knots([0.95, 1.05], count);
            assert_eq!(k.len(), count);
            assert!(
                k.iter()
                    .all(|x| (x - 1.0).abs() >= MIN_KNOT_SPACING - 1e-12),
                "{count}: {k:?}"
            );
        }
        // Any count up to what fits: increasing, a spacing apart and from the anchor (a short
        // side takes no more than it holds).
        for range in [[0.7, 1.04], [0.96, 1.2], [0.5, 1.05], [0.9, 1.0]] {
            for count in 1..=knots_that_fit(range) {
                let k = knots(range, count);
                assert_eq!(k.len(), count, "{range:?}");
                assert!(
                    k.windows(2)
                        .all(|w| w[1] - w[0] >= MIN_KNOT_SPACING - 1e-12)
                        && k.iter()
                            .all(|x| (x - 1.0).abs() >= MIN_KNOT_SPACING - 1e-12),
                    "{range:?} {count}: {k:?}"
                );
            }
        }
    }

    #[test]
    fn knot_count_follows_the_distinct_speeds() {
        let count = |v: &[f64], max| {
            let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            knot_limit(distinct_speeds(v, [lo, hi]), [lo, hi], max).0
        };
        assert_eq!(count(&[0.7, 0.8, 0.9, 1.0], 4), 2);
        assert_eq!(count(&[0.7, 0.7, 1.0], 4), 1);
        assert_eq!(count(&[0.6, 0.65, 0.7, 0.75, 0.8, 0.85, 0.9, 1.0], 4), 4);
        // Speeds above the design count as much as those below, where the data reach beyond
        // the side's 0.03 there.
        assert_eq!(count(&[1.0, 1.02, 1.04, 1.06, 1.08], 6), 3);
        assert_eq!(count(&[0.7, 0.8, 0.9, 1.02, 1.025], 6), 2);
        assert_eq!(knot_limit(0, [1.0, 1.0], 4).0, 0);
        // The reason names what set the count.
        assert!(knot_limit(3, [0.7, 1.0], 4)
            .1
            .contains("one fewer than the data's 3"));
        assert!(knot_limit(9, [0.7, 1.0], 4)
            .1
            .starts_with("the most a curve gets"));
        assert!(knot_limit(9, [0.95, 1.0], 6)
            .1
            .contains("apart between the data's speeds 0.950…1.000"));
    }
}
