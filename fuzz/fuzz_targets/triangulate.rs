//! Feeds arbitrary bytes, decoded as points and constraint segments on a
//! small fixed scene, to the patch triangulation: it must return a mesh that
//! validates, never panic. tests/fuzz_corpus.rs replays
//! fuzz/corpus/triangulate and fuzz/regressions/triangulate on stable.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Err(e) = nusselt::fuzz::fuzz_triangulate(data) {
        panic!("{e}");
    }
});
