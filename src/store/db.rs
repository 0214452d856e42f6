//! [`Db`]: the database as the detector, the diagnosis worker and the wash advice see it —
//! reads through one connection, writes as typed requests, each one transaction.
//!
//! Two kinds of `Db`: a [`Store`] of their own (replay, the commands, tests: reads and writes
//! on the same connection) and [`ViaWriter`] (the daemon: reads through the task's read-only
//! connection, writes sent to the one writer, which owns the writable connection, and waited
//! for). The code that decides what to write (`detect`, `worker`, `advice`) is the same for
//! both. Must not hold SQL (that is the store's other files) or decide what to write.

use super::{
    AdviceWrite, NewGapAnalysis, NewOutcome, ScanWrite, Store, StoreError, WriteCmd, WriterHandle,
};

/// Reads through [`Db::read`], writes through the typed requests below.
pub trait Db {
    /// The connection to read through (read-only in the daemon).
    fn read(&self) -> &Store;
    /// One detector scan's segments and progress ([`Store::store_scan`]).
    fn write_scan(&mut self, scan: ScanWrite) -> Result<u64, StoreError>;
    /// One segment's diagnosis outcome ([`Store::store_outcome`]): the result ids.
    fn write_outcome(&mut self, outcome: NewOutcome) -> Result<Vec<i64>, StoreError>;
    /// One refresh of the wash advice ([`Store::store_advice`]): the ids of the washes.
    fn write_advice(&mut self, advice: AdviceWrite) -> Result<Vec<i64>, StoreError>;
    /// One gap analysis ([`Store::insert_gap_analysis`]): its id.
    fn write_gap_analysis(&mut self, analysis: NewGapAnalysis) -> Result<i64, StoreError>;
}

impl Db for Store {
    fn read(&self) -> &Store {
        self
    }

    fn write_scan(&mut self, scan: ScanWrite) -> Result<u64, StoreError> {
        self.store_scan(&scan)
    }

    fn write_outcome(&mut self, outcome: NewOutcome) -> Result<Vec<i64>, StoreError> {
        self.store_outcome(&outcome)
    }

    fn write_advice(&mut self, advice: AdviceWrite) -> Result<Vec<i64>, StoreError> {
        self.store_advice(&advice)
    }

    fn write_gap_analysis(&mut self, analysis: NewGapAnalysis) -> Result<i64, StoreError> {
        self.insert_gap_analysis(&analysis)
    }
}

/// The daemon's `Db`: reads through `read`, writes through the writer task and waits for its
/// answer. Blocking: use it on tokio's blocking pool (where the daemon's tasks run their store
/// work), never on the async runtime.
pub struct ViaWriter<'a> {
    pub read: &'a Store,
    pub writer: &'a WriterHandle,
}

impl Db for ViaWriter<'_> {
    fn read(&self) -> &Store {
        self.read
    }

    fn write_scan(&mut self, scan: ScanWrite) -> Result<u64, StoreError> {
        self.writer
            .blocking_request(|reply| WriteCmd::Detection { scan, reply })
    }

    fn write_outcome(&mut self, outcome: NewOutcome) -> Result<Vec<i64>, StoreError> {
        self.writer
            .blocking_request(|reply| WriteCmd::Diagnosis { outcome, reply })
    }

    fn write_advice(&mut self, advice: AdviceWrite) -> Result<Vec<i64>, StoreError> {
        self.writer
            .blocking_request(|reply| WriteCmd::Advice { advice, reply })
    }

    fn write_gap_analysis(&mut self, analysis: NewGapAnalysis) -> Result<i64, StoreError> {
        self.writer.blocking_request(|reply| WriteCmd::GapAnalysis {
            analysis: Box::new(analysis),
            reply,
        })
    }
}
