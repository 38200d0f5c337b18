//! Feeds arbitrary bytes to the glTF loader: it must return, never panic.
//! Crashes found here become named tests (tests/fuzz_corpus.rs replays
//! fuzz/corpus/load_gltf and fuzz/regressions on stable).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    nusselt::fuzz::fuzz_load(data);
});
