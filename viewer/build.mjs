// Bundles the viewer (src/main.js with three.js and the web binding) into one script and puts it
// where `mocodec view` reads it: encoder/mocodec/view/static/viewer.js. The page it runs in is
// encoder/mocodec/view/page.html; the wasm is copied beside the script by `make web`.
import { build } from "esbuild";
import { mkdirSync } from "node:fs";
import { fileURLToPath } from "node:url";

const here = (p) => fileURLToPath(new URL(p, import.meta.url));
// --out DIR builds elsewhere (run_tests.sh compares such a build with the committed one).
const at = process.argv.indexOf("--out");
const out = at > 0 ? `${process.argv[at + 1].replace(/\/$/, "")}/` : here("../encoder/mocodec/view/static/");
mkdirSync(out, { recursive: true });
await build({
  entryPoints: [here("src/main.js")],
  bundle: true,
  format: "esm",
  minify: true,
  target: "es2020",
  legalComments: "eof",
  outfile: `${out}viewer.js`,
  logLevel: "warning",
});
