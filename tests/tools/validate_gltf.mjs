// Validates a .glb/.gltf with the Khronos glTF validator (npm package
// gltf-validator, installed into web/node_modules by `npm ci --prefix web`).
//
//   node tests/tools/validate_gltf.mjs FILE.glb [--allow-warning CODE]...
//
// Prints the validator's report (JSON) and exits 0 when it has no errors and
// no warnings (except the allowed codes), 1 when it has, 2 on bad usage or
// when the validator is not installed. Infos and hints never fail.
import { readFile } from 'node:fs/promises';
import { createRequire } from 'node:module';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const webDir = path.resolve(here, '..', '..', 'web');

const args = process.argv.slice(2);
const allowed = new Set();
let file = null;
for (let i = 0; i < args.length; ++i) {
  if (args[i] === '--allow-warning' && i + 1 < args.length) {
    allowed.add(args[++i]);
  } else if (file === null && !args[i].startsWith('--')) {
    file = args[i];
  } else {
    console.error(`validate_gltf: unexpected argument '${args[i]}'`);
    process.exit(2);
  }
}
if (file === null) {
  console.error('usage: node tests/tools/validate_gltf.mjs FILE.glb [--allow-warning CODE]...');
  process.exit(2);
}

let validator;
try {
  validator = createRequire(path.join(webDir, 'package.json'))('gltf-validator');
} catch (e) {
  console.error(`validate_gltf: gltf-validator is not installed in ${webDir}/node_modules ` +
                `(run scripts/bootstrap.sh deps, or npm ci --prefix web): ${e.message}`);
  process.exit(2);
}

const bytes = new Uint8Array(await readFile(file));
const report = await validator.validateBytes(bytes, {
  uri: path.basename(file),
  maxIssues: 0,  // unlimited
  // A .glb is self-contained: any external reference is a defect.
  externalResourceFunction: (uri) => Promise.reject(new Error(`external resource '${uri}' in a .glb`)),
});
console.log(JSON.stringify(report, null, 2));

const failing = report.issues.messages.filter(
  (m) => m.severity === 0 || (m.severity === 1 && !allowed.has(m.code)));
if (failing.length > 0) {
  for (const m of failing) {
    console.error(`validate_gltf: ${m.severity === 0 ? 'error' : 'warning'} ${m.code} at ${m.pointer ?? ''}: ${m.message}`);
  }
  process.exit(1);
}
console.error(`validate_gltf: ${file}: ${report.issues.numErrors} errors, ${report.issues.numWarnings} warnings, ` +
              `${report.issues.numInfos} infos, ${report.issues.numHints} hints`);
