//! The `objnerf` command line. Everything it does is in `cli/`: parse, call the library, print.

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
