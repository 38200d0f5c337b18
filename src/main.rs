//! The `nusselt` binary: everything is in [`cli`].

// `!(x > y)` rejects NaN along with out-of-range values, on purpose.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
