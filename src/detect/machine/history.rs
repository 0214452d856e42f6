//! The detector's recent frames and what it reads from them: values at a time, medians and
//! noise over spans, the level before a change and the knee where a ramp began, plus the
//! robust statistics (median, noise from successive differences, a least-squares line) they
//! and the phase rules use.
//!
//! Must not decide phases (that is the machine's); pure arithmetic over the history.

use super::{Frame, Machine, CONTEXT_FRAMES};

impl Machine {
    pub(super) fn trim_history(&mut self) {
        if self.hist.len() > CONTEXT_FRAMES {
            let cut = self.hist.len() - CONTEXT_FRAMES;
            self.hist.drain(..cut);
        }
    }

    pub(super) fn index_at_or_after(&self, t_ms: i64) -> usize {
        self.hist.partition_point(|x| x.t_ms < t_ms)
    }

    /// Value of the last frame at or before `t_ms` (the first frame if none).
    pub(super) fn value_at(&self, t_ms: i64, get: impl Fn(&Frame) -> f64) -> f64 {
        let i = self.hist.partition_point(|x| x.t_ms <= t_ms);
        self.hist.get(i.saturating_sub(1)).map_or(0.0, get)
    }

    /// A signal's values over the frames from `from_ms` to `to_ms`, both included.
    fn values_between(&self, from_ms: i64, to_ms: i64, get: impl Fn(&Frame) -> f64) -> Vec<f64> {
        self.hist
            .iter()
            .filter(|x| x.t_ms >= from_ms && x.t_ms <= to_ms)
            .map(get)
            .collect()
    }

    /// The median of a signal from `from_ms` to `to_ms`.
    pub(super) fn median_between(
        &self,
        from_ms: i64,
        to_ms: i64,
        get: impl Fn(&Frame) -> f64,
    ) -> f64 {
        median(self.values_between(from_ms, to_ms, get))
    }

    /// The noise of a signal from `from_ms` to `to_ms` ([`noise`]).
    pub(super) fn noise_between(
        &self,
        from_ms: i64,
        to_ms: i64,
        get: impl Fn(&Frame) -> f64,
    ) -> f64 {
        noise(&self.values_between(from_ms, to_ms, get))
    }

    /// Level of a signal over the frames before the newest one (median of up to 30).
    pub(super) fn level_before(&self, now_ms: i64, get: impl Fn(&Frame) -> f64) -> f64 {
        let v: Vec<f64> = self
            .hist
            .iter()
            .rev()
            .filter(|x| x.t_ms < now_ms)
            .take(30)
            .map(get)
            .collect();
        median(v)
    }

    /// The GG speed level the newest frames have held for the last `hold_ms` (every frame then
    /// within 0.5 % of their median, or 4 noise σ where the readings are noisier), and where
    /// that hold began (the first frame after the last one outside that band, walking back
    /// from the newest); `None` while the frames rise or fall or span less than `hold_ms`.
    pub(super) fn n1_plateau(&self, now_ms: i64, hold_ms: i64) -> Option<(f64, i64)> {
        let from = now_ms - hold_ms;
        let lo = self.index_at_or_after(from);
        let win = &self.hist[lo..];
        // Each frame may stand for up to a second: the window must be covered.
        let (first, last) = (win.first()?, win.last()?);
        if win.len() < 5 || last.t_ms - first.t_ms < hold_ms * 9 / 10 {
            return None;
        }
        let speeds: Vec<f64> = win.iter().map(|x| x.n1).collect();
        let level = median(speeds.clone());
        let band = (0.005 * level).max(4.0 * noise(&speeds));
        if speeds.iter().any(|v| (v - level).abs() > band) {
            return None;
        }
        let mut i = lo;
        while i > 0 && (self.hist[i - 1].n1 - level).abs() <= band {
            i -= 1;
        }
        Some((level, self.hist[i].t_ms))
    }

    /// Walks back from the newest frame to the last one within `band` of `level`: the knee
    /// where a plateau turned into the current ramp.
    pub(super) fn knee_back(&self, get: impl Fn(&Frame) -> f64, level: f64, band: f64) -> i64 {
        let mut i = self.hist.len().saturating_sub(1);
        while i > 0 && (get(&self.hist[i]) - level).abs() > band {
            i -= 1;
        }
        self.hist.get(i).map_or(0, |x| x.t_ms)
    }
}

/// The median of `v`, 0 for none (a span with no frame reads as no signal).
pub(super) fn median(v: Vec<f64>) -> f64 {
    crate::optim::median(v).unwrap_or(0.0)
}

/// Robust noise estimate: spread of successive differences about their median (a clean ramp
/// has none), scaled to a Gaussian sigma.
pub(super) fn noise(v: &[f64]) -> f64 {
    if v.len() < 3 {
        return 0.0;
    }
    let d: Vec<f64> = v.windows(2).map(|w| w[1] - w[0]).collect();
    let m = median(d.clone());
    let mad = median(d.iter().map(|x| (x - m).abs()).collect());
    1.4826 * mad / std::f64::consts::SQRT_2
}

/// Least-squares line through (x, y); `None` with fewer than 2 distinct x.
pub(super) fn line_fit(pts: &[(f64, f64)]) -> Option<(f64, f64)> {
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let slope = sxy / sxx;
    Some((slope, my - slope * mx))
}
