//! The `lapidary` command line: a thin front end that parses arguments,
//! calls the library, prints, and maps errors to exit codes (0 success,
//! 1 bad input, 2 usage).

mod cli;

fn main() {
    std::process::exit(cli::run());
}
