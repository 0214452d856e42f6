//! The benchmarks (`gtwatch bench <kind>`), one file per kind: each runs its measurement and
//! prints its report (JSON, or text where the kind has a text form) on stdout. The command line
//! (`cli::bench`) parses the flags and hands over what it loaded (engine, fit settings).
//! Benchmarks are never tests: they time and measure, they assert nothing.

pub mod daemon;
pub mod diagnosis;
pub mod gap;
mod ingest;
pub mod month;
pub mod replay;
pub mod sim;
pub mod soak;
pub mod steady;
pub mod wash;
