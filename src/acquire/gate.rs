//! The bad-value policy (`crate::quality`, the `[quality]` section) applied to polled samples:
//! the same range, stuck and spike rules as CSV replay, per tag, in time order.
//!
//! Flagged values are kept with their code (never stored as good) and counted. The spike rule
//! needs the next reading, so each tag's latest sample is held back one poll; [`Gate::finish`]
//! releases the held ones at shutdown. Pure: no I/O, no clock.

use crate::quality::{Point, Quality, QualityConfig, QualityCounts, SpikeFilter, ValueChecker};
use crate::signals::Signal;
use crate::store::{Sample, TagId};
use std::collections::HashMap;

use super::modbus::PollPlan;

struct TagGate {
    checker: ValueChecker,
    spikes: SpikeFilter,
}

/// Per-tag checkers for one poll plan.
pub(crate) struct Gate {
    tags: HashMap<TagId, TagGate>,
    n1_tag: Option<TagId>,
    counts: QualityCounts,
}

impl Gate {
    pub(crate) fn new(plan: &PollPlan, quality: &QualityConfig) -> Gate {
        let mut tags = HashMap::new();
        let mut n1_tag = None;
        for (tag, f) in plan.requests.iter().flat_map(|r| r.fields.iter()) {
            if f.signal == Some(Signal::N1) && n1_tag.is_none() {
                n1_tag = Some(*tag);
            }
            let checker = quality.checker(&[f.name.as_str()], f.signal);
            tags.insert(
                *tag,
                TagGate {
                    spikes: SpikeFilter::new(checker.limits()),
                    checker,
                },
            );
        }
        Gate {
            tags,
            n1_tag,
            counts: QualityCounts::default(),
        }
    }

    /// Classifies one poll's samples (all at one time); returns the samples released with
    /// their final quality (the previous poll's, for tags under the spike rule).
    pub(crate) fn apply(&mut self, batch: &[Sample]) -> Vec<Sample> {
        let n1 = self.n1_tag.and_then(|t| {
            batch
                .iter()
                .find(|s| s.tag == t && s.quality == Quality::Good)
                .map(|s| s.value)
        });
        let mut out = Vec::with_capacity(batch.len());
        for s in batch {
            let Some(g) = self.tags.get_mut(&s.tag) else {
                self.counts.add(s.quality);
                out.push(*s);
                continue;
            };
            // A value the register map already flagged keeps its code; the checker still sees
            // it (a bad value breaks a freeze).
            let checked = g.checker.check(s.t_ms, s.value, n1);
            let quality = if s.quality == Quality::Good {
                checked
            } else {
                s.quality
            };
            let point = Point {
                t_ms: s.t_ms,
                value: s.value,
                quality,
            };
            if let Some(p) = g.spikes.push(point) {
                self.counts.add(p.quality);
                out.push(Sample {
                    tag: s.tag,
                    t_ms: p.t_ms,
                    value: p.value,
                    quality: p.quality,
                });
            }
        }
        out
    }

    /// Releases every held sample (end of acquisition).
    pub(crate) fn finish(&mut self) -> Vec<Sample> {
        let mut out = Vec::new();
        for (tag, g) in self.tags.iter_mut() {
            if let Some(p) = g.spikes.finish() {
                self.counts.add(p.quality);
                out.push(Sample {
                    tag: *tag,
                    t_ms: p.t_ms,
                    value: p.value,
                    quality: p.quality,
                });
            }
        }
        out.sort_by_key(|s| (s.t_ms, s.tag));
        out
    }
}

#[cfg(test)]
#[path = "gate_tests.rs"]
mod tests;
