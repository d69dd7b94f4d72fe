//! The `pneuflex` command line: argument parsing, progress and wiring only.
fn main() {}
