// `make web`: bundle web/src/three-entry.js (three.js and the addons the pages use) into one
// minified ES module, src/facadeforge/editor/static/vendor/three.bundle.js, shipped in the
// Python package so that `facadeforge edit` and `facadeforge view` work offline.
import { readFileSync } from 'node:fs';
import * as esbuild from 'esbuild';

const version = (name) =>
  JSON.parse(readFileSync(new URL(`./node_modules/${name}/package.json`, import.meta.url))).version;

await esbuild.build({
  entryPoints: [new URL('./src/three-entry.js', import.meta.url).pathname],
  bundle: true,
  format: 'esm',
  minify: true,
  legalComments: 'eof',
  banner: { js: `/* three.js ${version('three')} (MIT), bundled by esbuild ${version('esbuild')} ` +
                `from web/src/three-entry.js: make web */` },
  outfile: new URL('../src/facadeforge/editor/static/vendor/three.bundle.js', import.meta.url).pathname,
});
