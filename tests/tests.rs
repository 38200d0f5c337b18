//! Integration tests, one module per topic; what every module shares is in
//! `fixtures`.

// Shared helpers: slow-test gate, scenes, glTF writers/readers, the binary, thread pools.
mod fixtures;

// Adaptive area sampling: closed forms to its tolerance, occluders, its error estimate.
mod area_sampling;
// The bake keeps the input's nodes, transforms, cameras, materials and texture coordinates.
mod bake;
// Resource budgets (links, elements, memory) stop refinement within limits.
mod budgets;
// Charts: convergence charts from synthetic reports, line charts, log axes, errors.
mod chart;
// Classic solvers and matrix kernels on closed boxes: furnace, closure, reciprocity.
mod classic;
// The command line on bad input: one `error:` line, exit code 1, no partial output.
mod cli;
// Form-factor kernels against Howell's closed forms.
mod closed_forms;
// Clustering: same solutions with and without, sub-quadratic link growth.
mod clustering;
// A run's files all or nothing: kill -9 in the write phase, Ctrl-C, leftovers, earlier runs' files.
mod commit;
// `nusselt compare`: image metrics, the reference-noise correction, exit codes.
mod compare;
// The whole `solve` command is bit-identical across runs and thread counts.
mod determinism;
// Discontinuity segments: closed-form penumbrae, contacts, determinism, work bounds.
mod discontinuity;
// `nusselt solve` end to end: every output reads back and conserves energy.
mod end_to_end;
// The failure-mode table on the stress scenes.
mod failure_table;
// The fuzz corpus and pseudo-random inputs through the fuzz targets' bodies.
mod fuzz_corpus;
// The hard interiors: energy closure per scene and preset, no light through a sealed wall, a point table, light through a baffle.
mod hard;
// The hierarchical solver: identities, agreement with a uniform solve, shadows.
mod hierarchical;
// View importance: fewer elements, as accurate in the view.
mod importance;
// Lightmaps: the atlas agrees with the mesh, no holes, TEXCOORD_1, the bake's atlas.
mod lightmap;
// Punctual lights and the sky: closed forms, energy, sharp shadows, the path tracer.
mod lights;
// The glTF loader: the scene contract, and hostile or malformed input refused.
mod loader;
// Sizes from input or flags refused before allocation, the binary run under an address-space limit.
mod memory_limit;
// The output mesh in its three modes: validity, contact lines, adaptivity.
mod meshing;
// Output encoders, readers and atomic writing.
mod output;
// The penumbra scene's closed form and the solver's error against it.
mod penumbra;
// The same scene at any scale gives the same solution and image.
mod precision;
// The path-traced reference: closed forms, noise as error predictor, CLI.
mod reference;
// The scale-up office family: triangle counts, validity, deterministic writing.
mod scale_scenes;
// The JSON Schemas: equal to the types' and met by every JSON output.
mod schema;
// The bundled scenes: up to date with the generator, well formed.
mod scenes;
// The stress scenes: invariants every method keeps where methods fail.
mod stress;
// `nusselt study`: rows, charts, cached reference.
mod study;
// Patch triangulation: crack-free meshes with points and constraint segments.
mod triangulate;
// The wireframe overlay and its compositing into `render.png`.
mod wireframe;
