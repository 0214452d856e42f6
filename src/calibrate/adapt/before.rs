//! The model before the adaptation at the baseline's points, as the adaptation's checks
//! (`similarity`, `surge`) compare every candidate against it: each point solved once, however
//! many candidates [`super::adapt`] fits and checks (up to three on the unit of
//! `tests/foreign_ambient.rs`).
//!
//! What it must not do: I/O; solve anything but the file before the adaptation.

use super::super::problem::CalibrationPoint;
use super::similarity::{moves, Moves};
use super::surge::margin;
use crate::engine::Engine;
use std::cell::OnceCell;

/// The file before the adaptation and, per baseline point, what the checks read on it, each
/// computed when first asked for.
pub struct Before<'a> {
    engine: &'a Engine,
    points: &'a [CalibrationPoint],
    moves: Vec<OnceCell<Option<Moves>>>,
    margins: Vec<OnceCell<Option<f64>>>,
}

impl<'a> Before<'a> {
    /// `engine` (the file before the adaptation) at `points`.
    pub fn new(engine: &'a Engine, points: &'a [CalibrationPoint]) -> Before<'a> {
        Before {
            engine,
            points,
            moves: points.iter().map(|_| OnceCell::new()).collect(),
            margins: points.iter().map(|_| OnceCell::new()).collect(),
        }
    }

    /// The moves of the non-dimensional values at point `i` between the shifted days
    /// (`similarity`), `None` where a solve fails or there is no such point.
    pub fn moves(&self, i: usize) -> Option<Moves> {
        let (cell, p) = (self.moves.get(i)?, self.points.get(i)?);
        *cell.get_or_init(|| moves(self.engine, p))
    }

    /// The surge margin of point `i`, % (`surge`), `None` where the solve fails.
    pub fn margin(&self, i: usize) -> Option<f64> {
        let (cell, p) = (self.margins.get(i)?, self.points.get(i)?);
        *cell.get_or_init(|| margin(self.engine, p))
    }
}
