//! The dynamic model's state vector and its layout.
//!
//! The first [`NX_CORE`] slots are the core engine's states (index constants `IX_*`, normalised
//! by design values so one tolerance fits all); each enabled effect owns a contiguous block after
//! them, placed by [`StateLayout`] when the model is built. The vector has a fixed capacity and
//! a length set by the layout, so it is `Copy` and the integrator never allocates per step.
//!
//! Only the model (`dynamic.rs`, `simulation.rs`) and the effects (through their own block)
//! read or write slots; controllers act through [`Actuator`], never by index. Pure data.

use std::ops::{Deref, DerefMut};

/// Number of core states.
pub(crate) const NX_CORE: usize = 7;
/// Core state indices.
pub(crate) const IX_P2: usize = 0;
pub(crate) const IX_T3: usize = 1;
pub(crate) const IX_P34: usize = 2;
pub(crate) const IX_N1: usize = 3;
pub(crate) const IX_N2: usize = 4;
pub(crate) const IX_FUEL_I: usize = 5;
pub(crate) const IX_FAR: usize = 6;
/// Scale of the fuel-air-ratio state.
pub(crate) const FAR_SCALE: f64 = 0.02;
/// Most states a model may have (core plus every effect's block): the integrator's limit.
pub(crate) const MAX_STATES: usize = super::integrator::MAX_DIM;

/// The state vector (normalised): a fixed-capacity vector whose length is the layout's.
#[derive(Clone, Copy, PartialEq)]
pub struct State {
    v: [f64; MAX_STATES],
    n: usize,
}

impl State {
    /// `n` zeros (`n` ≤ [`MAX_STATES`]; larger values are capped, which a [`StateLayout`]
    /// never asks for).
    pub fn zeros(n: usize) -> State {
        State {
            v: [0.0; MAX_STATES],
            n: n.min(MAX_STATES),
        }
    }

    /// A state from a slice (its length, capped at [`MAX_STATES`]).
    pub fn from_slice(x: &[f64]) -> State {
        let mut s = State::zeros(x.len());
        let n = s.n;
        s.v[..n].copy_from_slice(&x[..n]);
        s
    }
}

impl Deref for State {
    type Target = [f64];
    fn deref(&self) -> &[f64] {
        &self.v[..self.n]
    }
}

impl DerefMut for State {
    fn deref_mut(&mut self) -> &mut [f64] {
        &mut self.v[..self.n]
    }
}

impl std::fmt::Debug for State {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

/// Where each part of the model keeps its states: the core first, then one block per effect
/// (in the order the effects are listed).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct StateLayout {
    /// (offset, length) of each effect's block, in effect order.
    blocks: Vec<(usize, usize)>,
    len: usize,
}

/// A layout asks for more states than [`MAX_STATES`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("the enabled effects need {needed} states; the model holds at most {MAX_STATES}")]
pub struct TooManyStates {
    pub needed: usize,
}

impl StateLayout {
    /// The core alone.
    pub fn core() -> StateLayout {
        StateLayout {
            blocks: Vec::new(),
            len: NX_CORE,
        }
    }

    /// The core followed by blocks of the given sizes.
    pub fn with_blocks(sizes: &[usize]) -> Result<StateLayout, TooManyStates> {
        let mut blocks = Vec::with_capacity(sizes.len());
        let mut at = NX_CORE;
        for &n in sizes {
            blocks.push((at, n));
            at += n;
        }
        if at > MAX_STATES {
            return Err(TooManyStates { needed: at });
        }
        Ok(StateLayout { blocks, len: at })
    }

    /// Total number of states.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the layout is the core alone.
    pub fn is_core_only(&self) -> bool {
        self.len == NX_CORE
    }

    /// Never empty (the core is always there); provided for clippy's `len_without_is_empty`.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Slot range of effect block `i`.
    pub fn block(&self, i: usize) -> std::ops::Range<usize> {
        self.blocks
            .get(i)
            .map(|&(a, n)| a..a + n)
            .unwrap_or(NX_CORE..NX_CORE)
    }

    /// A zero state of this layout.
    pub fn zeros(&self) -> State {
        State::zeros(self.len)
    }
}

/// Normalisation of the core states (design values).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scales {
    pub p2: f64,
    pub t3: f64,
    pub p34: f64,
    pub n1: f64,
    pub n2: f64,
    pub fuel: f64,
}

/// One of the two shafts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shaft {
    /// Gas generator (n1).
    Gg,
    /// Power turbine (n2).
    Pt,
}

impl Shaft {
    /// The state slot of the shaft's speed.
    pub fn index(self) -> usize {
        match self {
            Shaft::Gg => IX_N1,
            Shaft::Pt => IX_N2,
        }
    }

    /// The speed scale of the shaft.
    pub fn scale(self, s: &Scales) -> f64 {
        match self {
            Shaft::Gg => s.n1,
            Shaft::Pt => s.n2,
        }
    }
}

/// What a controller may do to the running engine at a discrete transition: read the shaft
/// speeds, reset the fuel controller's integrator (a bumpless switch), hold a shaft at a speed
/// (the grid locks the PT; a GG at rest stops). The simulation hands it out; controllers never
/// see the state's layout.
pub struct Actuator<'a> {
    y: &'a mut State,
    scales: &'a Scales,
}

impl<'a> Actuator<'a> {
    pub fn new(y: &'a mut State, scales: &'a Scales) -> Actuator<'a> {
        Actuator { y, scales }
    }

    /// Speed of a shaft, rpm.
    pub fn speed_rpm(&self, shaft: Shaft) -> f64 {
        self.y[shaft.index()] * shaft.scale(self.scales)
    }

    /// Sets a shaft's speed, rpm (grid lock, rest).
    pub fn set_speed_rpm(&mut self, shaft: Shaft, rpm: f64) {
        self.y[shaft.index()] = rpm / shaft.scale(self.scales);
    }

    /// Sets the fuel controller's integrator, kg/s.
    pub fn set_fuel_integrator_kg_s(&mut self, value: f64) {
        self.y[IX_FUEL_I] = value / self.scales.fuel;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_places_blocks_after_the_core_and_refuses_too_many() {
        let l = StateLayout::with_blocks(&[4, 0, 2]).expect("fits");
        assert_eq!(l.len(), NX_CORE + 6);
        assert_eq!(l.block(0), NX_CORE..NX_CORE + 4);
        assert_eq!(l.block(1), NX_CORE + 4..NX_CORE + 4);
        assert_eq!(l.block(2), NX_CORE + 4..NX_CORE + 6);
        assert!(StateLayout::core().is_core_only());
        let e = StateLayout::with_blocks(&[MAX_STATES]).expect_err("too many");
        assert_eq!(e.needed, NX_CORE + MAX_STATES);
        let mut y = l.zeros();
        y[NX_CORE + 5] = 2.0;
        assert_eq!(y.len(), 13);
        assert_eq!(State::from_slice(&y), y);
    }

    #[test]
    fn actuator_speaks_rpm_and_kg_s() {
        let scales = Scales {
            p2: 1.0,
            t3: 1.0,
            p34: 1.0,
            n1: 10_000.0,
            n2: 3_000.0,
            fuel: 2.0,
        };
        let mut y = StateLayout::core().zeros();
        let mut a = Actuator::new(&mut y, &scales);
        a.set_speed_rpm(Shaft::Pt, 3_000.0);
        a.set_speed_rpm(Shaft::Gg, 5_000.0);
        a.set_fuel_integrator_kg_s(1.0);
        assert_eq!(a.speed_rpm(Shaft::Gg), 5_000.0);
        assert_eq!((y[IX_N2], y[IX_N1], y[IX_FUEL_I]), (1.0, 0.5, 0.5));
    }
}
