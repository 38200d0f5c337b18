// Validates a .gltf file (and the external buffers it references) with the
// Khronos glTF Validator (npm package `gltf-validator`).
//
// Usage: node tools/validate_gltf.mjs FILE.gltf
// Setup: npm install --prefix tools   (installs gltf-validator from tools/package.json)
//
// Prints a one-line summary and every error and warning, one per line.
// Exit status: 0 when the validator reports no error-severity message,
// 1 when it does or the file cannot be validated, 2 on a usage error.

import { readFile } from "node:fs/promises";
import { createRequire } from "node:module";
import path from "node:path";

const require = createRequire(import.meta.url);

function fail(message, code = 1) {
  console.error(`error: ${message}`);
  process.exit(code);
}

if (process.argv.length !== 3) {
  fail("usage: node tools/validate_gltf.mjs FILE.gltf", 2);
}
const file = path.resolve(process.argv[2]);

let validator;
try {
  validator = require("gltf-validator");
} catch {
  fail("gltf-validator is not installed: run `npm install --prefix tools`");
}

let bytes;
try {
  bytes = await readFile(file);
} catch (e) {
  fail(`cannot read ${file}: ${e.message}`);
}

const SEVERITY = ["error", "warning", "info", "hint"];

let report;
try {
  report = await validator.validateBytes(new Uint8Array(bytes), {
    uri: path.basename(file),
    format: file.endsWith(".glb") ? "glb" : "gltf",
    maxIssues: 0,
    writeTimestamp: false,
    externalResourceFunction: async (uri) => {
      const resource = path.resolve(path.dirname(file), decodeURIComponent(uri));
      return new Uint8Array(await readFile(resource));
    },
  });
} catch (e) {
  fail(`the validator could not process ${file}: ${e}`);
}

const issues = report.issues;
console.log(
  `glTF Validator ${validator.version()}: ${path.basename(file)}: ` +
    `${issues.numErrors} errors, ${issues.numWarnings} warnings, ` +
    `${issues.numInfos} infos, ${issues.numHints} hints`,
);
for (const m of issues.messages) {
  if (m.severity <= 1) {
    console.log(`  ${SEVERITY[m.severity]} ${m.code} at ${m.pointer ?? ""}: ${m.message}`);
  }
}
if (issues.numErrors > 0) {
  fail(`${path.basename(file)}: the glTF Validator reports ${issues.numErrors} error(s)`);
}
