// Builds the packages (ES modules and browser bundles) and copies them, the jsPsych bundle
// and the example pages into the Python package (src/tactorbelt/bridge/static/), which the
// wheel carries and `tactorbelt serve` serves.
//   node scripts/build.mjs           build and write
//   node scripts/build.mjs --check   build in memory; fail when the committed files differ
import * as esbuild from "esbuild";
import { readFileSync, writeFileSync, mkdirSync, existsSync } from "node:fs";
import { dirname, join, relative } from "node:path";
import { fileURLToPath } from "node:url";

const WEB = join(dirname(fileURLToPath(import.meta.url)), "..");
const STATIC = join(WEB, "..", "src", "tactorbelt", "bridge", "static");
const check = process.argv.includes("--check");

// `import ... from "jspsych"` in a browser bundle: the global of jsPsych's own bundle
const jspsychGlobal = {
  name: "jspsych-global",
  setup(build) {
    build.onResolve({ filter: /^jspsych$/ }, () => ({ path: "jspsych", namespace: "jspsych-global" }));
    build.onLoad({ filter: /.*/, namespace: "jspsych-global" }, () => ({
      contents: "module.exports = globalThis.jsPsychModule;",
      loader: "js",
    }));
  },
};

const PACKAGES = [
  { dir: "bridge-client", entry: "src/index.js", global: "TactorbeltBridge", named: true },
  { dir: "jspsych-plugin-tactile", entry: "src/index.js", global: "jsPsychTactile" },
  { dir: "jspsych-plugin-belt-response", entry: "src/index.js", global: "jsPsychBeltResponse" },
];

const outputs = new Map(); // path -> contents (string or Uint8Array)

async function bundle(options) {
  const result = await esbuild.build({
    bundle: true,
    write: false,
    target: "es2020",
    logLevel: "silent",
    legalComments: "inline",
    ...options,
  });
  return result.outputFiles[0].text;
}

for (const pkg of PACKAGES) {
  const root = join(WEB, "packages", pkg.dir);
  const meta = JSON.parse(readFileSync(join(root, "package.json"), "utf8"));
  const banner = `/*! ${meta.name} ${meta.version} (${meta.license}); built by web/scripts/build.mjs from web/packages/${pkg.dir}: do not edit */`;
  const entry = join(root, pkg.entry);
  const esm = await bundle({
    entryPoints: [entry],
    format: "esm",
    external: ["jspsych"],
    banner: { js: banner },
  });
  const iife = await bundle({
    entryPoints: [entry],
    format: "iife",
    globalName: pkg.global,
    plugins: [jspsychGlobal],
    banner: { js: banner },
    // a plugin's global is its class, as jsPsych's own browser bundles have it
    footer: pkg.named ? undefined : { js: `${pkg.global} = ${pkg.global}.default;` },
  });
  outputs.set(join(root, "dist", "index.js"), esm);
  outputs.set(join(root, "dist", "index.browser.js"), iife);
  outputs.set(join(STATIC, "plugins", `${pkg.dir}.mjs`), esm);
  outputs.set(join(STATIC, "plugins", `${pkg.dir}.js`), iife);
}

// jsPsych 8 (MIT): its browser bundle, its stylesheet, and one ES module for import maps
const jspsychDir = join(WEB, "node_modules", "jspsych");
const jspsychMeta = JSON.parse(readFileSync(join(jspsychDir, "package.json"), "utf8"));
outputs.set(join(STATIC, "vendor", "jspsych.js"), readFileSync(join(jspsychDir, "dist", "index.browser.js"), "utf8"));
outputs.set(join(STATIC, "vendor", "jspsych.css"), readFileSync(join(jspsychDir, "css", "jspsych.css"), "utf8"));
outputs.set(
  join(STATIC, "vendor", "jspsych.mjs"),
  await bundle({
    entryPoints: [join(jspsychDir, "dist", "index.js")],
    format: "esm",
    banner: { js: `/*! jspsych ${jspsychMeta.version} (${jspsychMeta.license}), bundled with its dependencies by web/scripts/build.mjs */` },
  }),
);
outputs.set(join(STATIC, "vendor", "LICENSE-jspsych.txt"), readFileSync(join(WEB, "vendor-licenses", "jspsych.txt"), "utf8"));
outputs.set(join(STATIC, "examples", "paper.html"), readFileSync(join(WEB, "examples", "paper.html"), "utf8"));

let stale = [];
for (const [path, contents] of outputs) {
  const inPackage = path.startsWith(STATIC);
  if (check) {
    if (!inPackage) continue;
    const now = existsSync(path) ? readFileSync(path, "utf8") : null;
    if (now !== contents) stale.push(relative(join(WEB, ".."), path));
  } else {
    mkdirSync(dirname(path), { recursive: true });
    writeFileSync(path, contents);
  }
}
if (check) {
  if (stale.length) {
    console.error(`the committed bundles differ from a fresh build (run \`make web\`):\n  ${stale.join("\n  ")}`);
    process.exit(1);
  }
  console.log(`bundles up to date: ${[...outputs.keys()].filter((p) => p.startsWith(STATIC)).length} files in src/tactorbelt/bridge/static`);
} else {
  console.log(`built ${outputs.size} files`);
}
