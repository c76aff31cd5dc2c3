//! The `strata` command line: `render`, `study`, `merge`.

use std::process::ExitCode;

fn main() -> ExitCode {
    strata::cli::main()
}
