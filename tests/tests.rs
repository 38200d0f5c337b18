//! Integration tests, one module per topic.

mod cli;
mod classic;
mod closed_forms;
mod end_to_end;
mod util;
