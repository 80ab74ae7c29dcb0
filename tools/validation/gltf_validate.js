// Runs the Khronos glTF Validator (npm package gltf-validator) on .gltf / .glb files.
//
//   node tools/validation/gltf_validate.js [--all] FILE...
//
// Prints, per file, the counts of errors, warnings, infos and hints, then each issue code
// once with its count, its severity and its first message (--all: every message). Buffers
// and images a .gltf refers to by URI are read from its folder.
// Exit status: 0 when no file has an error, 1 when some file has one, 2 for a usage error or
// a file that cannot be read. Where the package lives outside the usual node_modules lookup
// (tools/setup.sh installs it into the checkout's git-ignored node_modules/), NODE_PATH
// names its node_modules folder.
'use strict';
const fs = require('fs');
const path = require('path');

const kSeverity = ['error', 'warning', 'info', 'hint'];

function usage() {
  process.stderr.write('usage: node gltf_validate.js [--all] FILE...\n');
  process.exit(2);
}

function loadValidator() {
  try {
    return require('gltf-validator');
  } catch (e) {
    process.stderr.write('gltf_validate.js: the npm package gltf-validator is not installed ' +
                         '(tools/setup.sh installs it; or set NODE_PATH to the node_modules folder that holds it)\n');
    process.exit(2);
  }
}

function readResource(file) {
  return (uri) => new Promise((resolve, reject) => {
    try {
      resolve(new Uint8Array(fs.readFileSync(path.resolve(path.dirname(file), decodeURIComponent(uri)))));
    } catch (e) {
      reject(e.toString());
    }
  });
}

/// One line per issue code, most severe first: count, severity, code, first pointer and message.
function printByCode(messages) {
  const byCode = new Map();
  for (const m of messages) {
    const entry = byCode.get(m.code);
    if (entry) entry.count++;
    else byCode.set(m.code, {count: 1, first: m});
  }
  const codes = [...byCode.values()].sort((a, b) => a.first.severity - b.first.severity);
  for (const {count, first} of codes)
    console.log(`  ${kSeverity[first.severity]} ${first.code} ×${count}: ${first.pointer || ''} ${first.message}`);
}

async function main() {
  const args = process.argv.slice(2);
  const all = args.includes('--all');
  const files = args.filter((a) => a !== '--all');
  if (files.length === 0 || files.some((f) => f.startsWith('-'))) usage();
  const validator = loadValidator();
  console.log(`gltf-validator ${validator.version()}`);
  let withErrors = 0;
  for (const file of files) {
    let bytes;
    try {
      bytes = new Uint8Array(fs.readFileSync(file));
    } catch (e) {
      process.stderr.write(`gltf_validate.js: ${file}: ${e.message}\n`);
      process.exit(2);
    }
    const report = await validator.validateBytes(bytes, {
      uri: path.basename(file),
      maxIssues: 0,  // every issue, so that the counts are exact
      externalResourceFunction: readResource(file),
    });
    const n = report.issues;
    console.log(`${file}: ${n.numErrors} errors, ${n.numWarnings} warnings, ${n.numInfos} infos, ${n.numHints} hints`);
    if (all)
      for (const m of n.messages) console.log(`  ${kSeverity[m.severity]} ${m.code} ${m.pointer || ''}: ${m.message}`);
    else
      printByCode(n.messages);
    if (n.numErrors > 0) withErrors++;
  }
  if (withErrors > 0) console.log(`${withErrors} of ${files.length} files have errors`);
  process.exit(withErrors > 0 ? 1 : 0);
}

main().catch((e) => {
  process.stderr.write(`gltf_validate.js: ${e.stack || e}\n`);
  process.exit(2);
});
