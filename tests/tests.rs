//! Integration tests, one module per topic.

mod budgets;
mod chart;
mod classic;
mod cli;
mod closed_forms;
mod clustering;
mod compare;
mod determinism;
mod discontinuity;
mod end_to_end;
mod failure_table;
mod fuzz_corpus;
mod hierarchical;
mod importance;
mod loader;
mod meshing;
mod output;
mod penumbra;
mod reference;
mod scale_scenes;
mod scenes;
mod stress;
mod study;
mod triangulate;
mod util;
mod wireframe;
