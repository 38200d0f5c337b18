//! Feeds arbitrary bytes, decoded as a tiny random scene (a few
//! parallelograms and triangles with random positions, reflectances and
//! emissions), to the hierarchical solve at preview accuracy and the output
//! mesh: no panic, finite non-negative radiosities and pixels, no energy
//! created. tests/fuzz_corpus.rs replays fuzz/corpus/pipeline and
//! fuzz/regressions/pipeline on stable.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Err(e) = nusselt::fuzz::fuzz_pipeline(data) {
        panic!("{e}");
    }
});
