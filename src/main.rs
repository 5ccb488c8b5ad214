//! The `furfit` binary: argument parsing and printing only; all work is in the library.

fn main() -> std::process::ExitCode {
    furfit::cli::main()
}
