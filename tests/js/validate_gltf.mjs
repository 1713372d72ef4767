// Validates glTF 2.0 files (.gltf or .glb) with the Khronos glTF Validator
// (npm gltf-validator, pinned in package.json; offline, no network):
//
//   node tests/js/validate_gltf.mjs FILE...
//
// External resources (buffers, images) are read from files next to the asset.
// Prints one summary line per file (validator version, counts of errors,
// warnings, infos and hints, and the resources it loaded) and every issue
// that is an error or a warning; `--json` prints the reports instead, one JSON
// object per line. Exits 1 when any file has an error, or a warning not on the
// ALLOWED list below; 2 on bad usage, an unreadable file or the module missing.
//
// ALLOWED warnings (intentional in the assets tests/python/gltf_assets.py
// writes; each one is still printed, marked "allowed"):
// - MESH_PRIMITIVE_GENERATED_TANGENT_SPACE: a material with a normal texture on
//   a primitive without a TANGENT attribute. The test assets omit tangents on
//   purpose so that a renderer's MikkTSpace generation is exercised; the
//   validator flags every such primitive as "runtime-generated tangent space
//   may be non-portable".
import { readFile } from "node:fs/promises";
import path from "node:path";

let validator;
try {
  validator = await import("gltf-validator");
} catch (e) {
  console.error(`gltf-validator is not installed (npm ci --prefix tests/js, as scripts/test-all.sh does): ${e.message}`);
  process.exit(2);
}

const ALLOWED = new Set(["MESH_PRIMITIVE_GENERATED_TANGENT_SPACE"]);
const SEVERITY = ["error", "warning", "info", "hint"];

const args = process.argv.slice(2);
const asJson = args.includes("--json");
const files = args.filter((a) => a !== "--json");
if (files.length === 0) {
  console.error("usage: node tests/js/validate_gltf.mjs [--json] FILE...");
  process.exit(2);
}

let failed = false;
for (const file of files) {
  let bytes;
  try {
    bytes = new Uint8Array(await readFile(file));
  } catch (e) {
    console.error(`${file}: cannot read: ${e.message}`);
    process.exit(2);
  }
  const dir = path.dirname(path.resolve(file));
  let report;
  try {
    report = await validator.validateBytes(bytes, {
      uri: path.basename(file),
      maxIssues: 0,
      writeTimestamp: false,
      externalResourceFunction: (uri) =>
        readFile(path.resolve(dir, decodeURIComponent(uri))).then(
          (b) => new Uint8Array(b),
          (e) => Promise.reject(e.toString()),
        ),
    });
  } catch (e) {
    console.error(`${file}: the validator refused the file: ${e}`);
    failed = true;
    continue;
  }
  const issues = report.issues;
  const bad = issues.messages.filter(
    (m) => m.severity === 0 || (m.severity === 1 && !ALLOWED.has(m.code)),
  );
  if (bad.length > 0) failed = true;
  if (asJson) {
    console.log(JSON.stringify({ file, ...report, failed: bad.length > 0 }));
    continue;
  }
  const loaded = (report.info?.resources ?? [])
    .map((r) => `${r.pointer} ${r.storage}${r.uri ? " " + r.uri : ""}${r.image ? ` ${r.image.width}x${r.image.height}` : ""}`)
    .join("; ");
  console.log(
    `${file}: ${bad.length > 0 ? "FAIL" : "ok"} (glTF Validator ${report.validatorVersion}): ` +
      `${issues.numErrors} errors, ${issues.numWarnings} warnings, ` +
      `${issues.numInfos} infos, ${issues.numHints} hints; ` +
      `${report.info?.drawCallCount ?? 0} draw calls, ${report.info?.totalVertexCount ?? 0} vertices; ` +
      `resources: ${loaded}`,
  );
  for (const m of issues.messages) {
    if (m.severity > 1) continue;
    const allowed = m.severity === 1 && ALLOWED.has(m.code) ? " (allowed)" : "";
    console.log(`  ${SEVERITY[m.severity]} ${m.code} at ${m.pointer ?? m.offset ?? ""}: ${m.message}${allowed}`);
  }
}
process.exit(failed ? 1 : 0);
