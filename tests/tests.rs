//! Integration tests, one module per topic.

mod cli;
mod end_to_end;
mod util;
