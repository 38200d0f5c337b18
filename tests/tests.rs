//! Integration tests, one module per topic.

mod classic;
mod cli;
mod closed_forms;
mod end_to_end;
mod fuzz_corpus;
mod hierarchical;
mod loader;
mod output;
mod scenes;
mod util;
