//! The `gtwatch` binary: hands the command line to `gtwatch::cli::main`. Must not hold any logic
//! of its own (everything, including argument parsing, lives in the library).

fn main() -> std::process::ExitCode {
    gtwatch::cli::main()
}
