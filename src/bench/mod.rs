//! The benchmarks (`gtwatch bench <kind>`), one file per kind: each runs its measurement and
//! prints its report (JSON, or text where the kind has a text form) on stdout. The command line
//! (`cli::bench`) parses the flags and hands over what it loaded (engine, fit settings).
//! Benchmarks are never tests: they time and measure, they assert nothing.

pub(crate) mod daemon;
pub(crate) mod diagnosis;
pub(crate) mod gap;
pub(crate) mod gap_month;
mod ingest;
pub(crate) mod month;
pub(crate) mod replay;
pub(crate) mod sim;
pub(crate) mod soak;
pub(crate) mod steady;
pub(crate) mod wash;
