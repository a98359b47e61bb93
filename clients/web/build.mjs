// Builds the viewer into a static folder: index.html + viewer.js (three.js bundled from
// node_modules by esbuild, so the page needs no network). Usage: node build.mjs OUTDIR
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import * as esbuild from 'esbuild';

const here = path.dirname(fileURLToPath(import.meta.url));
const out = process.argv[2];
if (!out) { console.error('usage: node build.mjs OUTDIR'); process.exit(2); }
fs.mkdirSync(out, { recursive: true });
await esbuild.build({
  entryPoints: [path.join(here, 'src/main.js')],
  bundle: true,
  format: 'iife',  // a classic script works from file:// too
  minify: true,
  target: 'es2020',
  outfile: path.join(out, 'viewer.js'),
  logLevel: 'warning',
});
fs.copyFileSync(path.join(here, 'index.html'), path.join(out, 'index.html'));
console.log(`built ${path.join(out, 'index.html')}`);
