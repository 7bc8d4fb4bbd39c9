// Validate a .glb/.gltf with the Khronos glTF-Validator and print its report as JSON.
// Usage: node validate.mjs FILE   (exit 0 when the report has no errors, 1 otherwise)
import { readFile } from 'node:fs/promises';
import validator from 'gltf-validator';

const file = process.argv[2];
const data = new Uint8Array(await readFile(file));
const report = await validator.validateBytes(data, { maxIssues: 100 });
console.log(JSON.stringify({
  file,
  numErrors: report.issues.numErrors,
  numWarnings: report.issues.numWarnings,
  messages: report.issues.messages.filter((m) => m.severity === 0).slice(0, 20),
  info: report.info,
}));
process.exit(report.issues.numErrors === 0 ? 0 : 1);
