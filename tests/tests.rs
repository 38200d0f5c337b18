//! Integration tests, one module per topic.

mod fuzz_corpus;
mod loader;
