fn main() -> std::process::ExitCode {
    gtwatch::cli::main()
}
