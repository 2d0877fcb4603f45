// `isocube view` in a real browser: Debian's Chromium driven by playwright-core (its own
// browser download is not reachable from our machines).
//
//   cd tests/browser && npm ci && node view.test.mjs ISOCUBE WORKDIR [--latency] [CHROMIUM]
//
// On sample:tangle:128: the page opens; three levels set through the slider give the triangle
// counts `isocube extract` gives at those levels; switching to ternary does too; the PLY the
// page downloads is byte for byte the command's file; the canvas is not blank and changes with
// the level. A segmentation's labels, a cage at two subdivision levels and a contour stack show
// the surfaces `extract --labels`, `subdivide` and `contours` make; a label toggles off and on.
// Also a page screenshot for the README. With --latency (a measurement, not a test:
// CI does not run it), on sample:tangle:256 in a browser of its own: the time from a slider move
// to the new picture over a sweep of levels, p50 / p95.

import { spawn, execFileSync } from "node:child_process";
import { readFileSync, mkdirSync } from "node:fs";
import { join } from "node:path";
import { fileURLToPath } from "node:url";
import assert from "node:assert/strict";
import { chromium } from "playwright-core";

const args = process.argv.slice(2);
const latency = args.includes("--latency");
const [isocube, work, executable = "/usr/bin/chromium"] = args.filter((a) => a !== "--latency");
assert.ok(isocube && work, "usage: node view.test.mjs ISOCUBE WORKDIR [CHROMIUM]");
mkdirSync(work, { recursive: true });

const repo = fileURLToPath(new URL("../..", import.meta.url));

/** Starts `isocube view INPUT [OPTIONS]` and resolves with its URL (the first line it prints). */
function serve(...input) {
  const child = spawn(isocube, ["view", ...input, "--no-open", "--quiet"], { stdio: ["ignore", "pipe", "inherit"] });
  return new Promise((resolve, reject) => {
    let out = "";
    child.stdout.on("data", (d) => {
      out += d;
      const line = out.split("\n")[0];
      // The page leaves first: its pending requests would otherwise meet a closed port.
      const stop = async () => {
        await page.goto("about:blank");
        child.kill();
      };
      if (out.includes("\n")) resolve({ url: line.trim(), stop });
    });
    child.on("exit", (code) => reject(new Error(`isocube view exited with ${code}`)));
    // No server outlives the test, whatever fails.
    process.on("exit", () => child.kill());
  });
}

/** The triangle count `isocube extract` reports for these arguments, and its file. */
function extract(volume, level, extra = []) {
  const out = join(work, `cli-${level}-${extra.join("")}.ply`);
  const run = execFileSync(isocube, ["extract", volume, "--level", String(level), "-o", out, ...extra], {
    encoding: "utf8",
    stdio: ["ignore", "pipe", "pipe"],
  });
  return out;
}
function trianglesOf(ply) {
  const head = readFileSync(ply).subarray(0, 400).toString("latin1");
  return Number(/element face (\d+)/.exec(head)[1]);
}

const launch = () =>
  chromium.launch({
    executablePath: executable,
    // Software WebGL (SwiftShader) where there is no GPU.
    args: ["--enable-unsafe-swiftshader", "--use-angle=swiftshader", "--ignore-gpu-blocklist"],
  });
let browser = await launch();
let context = await browser.newContext({ viewport: { width: 1280, height: 800 }, acceptDownloads: true });
let page = await context.newPage();
const errors = [];
// Requests the page has sent and not seen answered, for the diagnosis of a timeout.
const pending = new Set();
function watch(p) {
  p.on("request", (r) => pending.add(r));
  p.on("requestfinished", (r) => pending.delete(r));
  p.on("requestfailed", (r) => pending.delete(r));
  p.on("pageerror", (e) => {
    errors.push(String(e));
    console.log(`page error: ${e}`);
  });
  // The browser asks for /favicon.ico without the token: that 403 is the server's due.
  p.on("console", (m) => {
    if (m.type() === "error" && !m.text().includes("403")) console.log(`page console: ${m.text()}`);
  });
}
watch(page);

/** Waits for the page to have shown its first surfaces; says what it was doing if it does not. */
async function ready(timeout = 60000) {
  try {
    await page.waitForFunction(() => window.isocube && window.isocube.ready === true, null, { timeout, polling: 50 });
  } catch (e) {
    const state = await page
      .evaluate(() => ({
        status: document.querySelector("#status").textContent,
        triangles: document.querySelector("#triangles").textContent,
        pictures: window.isocube ? window.isocube.timings.length : null,
      }))
      .catch((err) => `the page does not answer: ${err}`);
    console.log(`page state at the timeout: ${JSON.stringify(state)}`);
    const routes = [...pending].map((r) => r.url().replace(/token=[0-9a-f]+/, "token=…"));
    console.log(`requests unanswered: ${routes.join(", ") || "none"}`);
    throw e;
  }
}
const figures = () => page.evaluate(() => window.isocube.figures());
const countShown = async () => Number((await page.locator("#triangles").textContent()).replace(/,/g, ""));

// ---- counts, ternary, download, pictures on tangle:128 -------------------------------------
{
  const volume = "sample:tangle:128";
  const server = await serve(volume);
  await page.goto(server.url);
  await ready();
  const info = await page.evaluate(() => ({ min: Number(document.querySelector("#level").min) }));
  const shots = [];
  for (const level of [-2, 0, 5]) {
    // Through the slider's own input event, as a drag does: the slider position for this level.
    await page.evaluate((l) => window.isocube.setLevel(l), level);
    const f = await figures();
    assert.equal(f.level, level);
    const cli = trianglesOf(extract(volume, level));
    assert.equal(await countShown(), cli, `level ${level}: page ${await countShown()}, isocube extract ${cli}`);
    assert.equal(f.triangles, cli);
    shots.push(await page.locator("#gl").screenshot());
    console.log(`level ${level}: ${cli} triangles on the page and from isocube extract`);
  }
  // A drag of the slider itself: the level it lands on is meshed and shown.
  await page.locator("#level").fill("3000");
  await page.waitForFunction(() => {
    const f = window.isocube.figures();
    return f && Math.abs(f.level - Number(document.querySelector("#levelnum").value)) < 1e-3;
  }, null, { polling: 50 });
  // The canvas is a picture, and a different one at another level.
  const distinct = (png) => new Set(png.subarray(0, png.length).toString("base64").match(/.{1,8}/g)).size;
  assert.ok(shots[0].length > 5000 && distinct(shots[0]) > 500, "the canvas looks blank");
  assert.ok(!shots[0].equals(shots[2]), "the picture did not change with the level");
  // Ternary.
  await page.evaluate((l) => window.isocube.setLevel(l), 0);
  await page.selectOption("#method", "ternary");
  await page.waitForFunction(() => window.isocube.figures() && document.querySelector("#method").value === "ternary", null, { polling: 50 });
  await page.waitForTimeout(200);
  await page.evaluate((l) => window.isocube.setLevel(l), 0);
  const ternaryFile = extract(volume, 0, ["--method", "ternary"]);
  assert.equal(await countShown(), trianglesOf(ternaryFile));
  console.log(`ternary at level 0: ${trianglesOf(ternaryFile)} triangles on the page and from isocube extract`);
  // Download the PLY: the command's file, byte for byte.
  const [download] = await Promise.all([page.waitForEvent("download"), page.click('a.dl[data-format="ply"]')]);
  const saved = join(work, "page.ply");
  await download.saveAs(saved);
  assert.ok(readFileSync(saved).equals(readFileSync(ternaryFile)), "the downloaded PLY differs from isocube extract's");
  console.log(`downloaded PLY (${readFileSync(saved).length} bytes) equals isocube extract's file`);
  await page.selectOption("#method", "mc");
  await page.click("#measure");
  await page.waitForFunction(() => document.querySelector("#minangle").textContent !== "–", null, { polling: 50 });
  // The README's picture: the panel from its top, the topology in.
  await page.waitForFunction(() => document.querySelector("#watertight").textContent !== "…", null, { polling: 50 });
  await page.evaluate(() => { document.querySelector("#side").scrollTop = 0; });
  await page.screenshot({ path: join(work, "view.png") });
  await server.stop();
}

// ---- a segmentation's labels, a cage, a contour stack -----------------------------------------
const shownParts = () => page.evaluate(() => window.isocube.parts());
{
  const labels = join(repo, "tests/data/volumes/labels.nii.gz");
  execFileSync(isocube, ["extract", labels, "--labels", "-o", join(work, "l.ply")], { stdio: "ignore" });
  const server = await serve(labels, "--labels");
  await page.goto(server.url);
  await ready();
  const shown = await shownParts();
  assert.ok(shown.length >= 2, `labels shown: ${shown.length}`);
  for (const p of shown) {
    const cli = trianglesOf(join(work, `l-${p.number}.ply`));
    assert.equal(p.figures.triangles, cli, `label ${p.number}`);
  }
  assert.equal(await page.locator("#partlist tr").count(), shown.length);
  const all = await page.locator("#gl").screenshot();
  await page.evaluate(() => window.isocube.toggle(0, false));
  const without = await page.locator("#gl").screenshot();
  assert.ok(!all.equals(without), "hiding a label did not change the picture");
  await page.evaluate(() => window.isocube.toggle(0, true));
  assert.ok(all.equals(await page.locator("#gl").screenshot()), "showing the label again did not restore the picture");
  await page.waitForFunction(() => document.querySelector("#watertight").textContent !== "…", null, { polling: 50 });
  await page.screenshot({ path: join(work, "view-labels.png") });
  console.log(`labels: ${shown.map((p) => `${p.number}: ${p.figures.triangles}`).join(", ")} triangles, as isocube extract --labels; a label toggles`);
  await server.stop();
}
{
  const server = await serve("sample:cube", "--levels", "1");
  await page.goto(server.url);
  await ready();
  assert.equal(await page.evaluate(() => window.isocube.lines()), 12, "the cube cage's edges");
  for (const levels of [2, 3]) {
    const file = join(work, `cube-${levels}.ply`);
    execFileSync(isocube, ["subdivide", "sample:cube", "--levels", String(levels), "-o", file], { stdio: "ignore" });
    await page.evaluate((n) => window.isocube.setLevels(n), levels);
    assert.equal((await figures()).triangles, trianglesOf(file), `${levels} levels`);
  }
  await page.screenshot({ path: join(work, "view-cage.png") });
  console.log("cage: the cube's 12 edges, its surface at 2 and 3 levels as isocube subdivide's");
  await server.stop();
}
{
  const file = join(work, "orebody.ply");
  execFileSync(isocube, ["contours", "sample:orebody", "-o", file], { stdio: "ignore" });
  const server = await serve("sample:orebody");
  await page.goto(server.url);
  await ready();
  const [ore] = await shownParts();
  assert.equal(ore.figures.triangles, trianglesOf(file));
  const contours = await page.evaluate(() => window.isocube.lines());
  assert.ok(contours > 100, `${contours} contour segments`);
  const shot = await page.locator("#gl").screenshot();
  await page.screenshot({ path: join(work, "view-contours.png") });
  await page.locator("#lines").uncheck();
  assert.ok(!shot.equals(await page.locator("#gl").screenshot()), "the contours are not drawn");
  console.log(`contour stack: ${ore.figures.triangles} triangles as isocube contours, ${contours} contour segments drawn`);
  await server.stop();
}

// ---- latency on a 256³ volume --------------------------------------------------------------
if (latency) {
  const server = await serve("sample:tangle:256");
  // A browser of its own: nothing of the first one's WebGL state or connections carries over.
  await browser.close();
  browser = await launch();
  context = await browser.newContext({ viewport: { width: 1280, height: 800 } });
  page = await context.newPage();
  watch(page);
  await page.goto(server.url);
  await ready(120000);
  // Slider positions from 20 % to 60 % of the range, one at a time as a slow drag gives them:
  // each waits for the first picture of its level (a preview on a coarser grid on a volume
  // this large); then a few positions each left to rest, waiting for the full surface.
  const sweep = (from, to, step, list) =>
    page.evaluate(
      async ([from, to, step, list]) => {
        const times = window.isocube[list];
        times.length = 0;
        const input = document.querySelector("#level");
        for (let s = from; s <= to; s += step) {
          input.value = String(s);
          const n = times.length;
          const deadline = performance.now() + 60000;
          const done = new Promise((resolve, reject) => {
            const poll = () =>
              times.length > n
                ? resolve()
                : performance.now() > deadline
                  ? reject(new Error(`no picture for slider position ${s} within 60 s`))
                  : setTimeout(poll, 1);
            poll();
          });
          input.dispatchEvent(new Event("input"));
          await done;
        }
        return [...times];
      },
      [from, to, step, list]
    );
  const stats = (times) => {
    times.sort((a, b) => a - b);
    const p = (q) => times[Math.min(times.length - 1, Math.floor(q * times.length))];
    return `p50 ${p(0.5).toFixed(0)} ms, p95 ${p(0.95).toFixed(0)} ms, max ${times[times.length - 1].toFixed(0)} ms`;
  };
  // Where the pictures' time went (medians): extraction on the server, the request in all
  // (extraction, encoding, transfer), the upload to WebGL, the drawing.
  const breakdown = async (coarse) => {
    const all = (await page.evaluate(() => window.isocube.timings)).filter((t) => t.coarse === coarse);
    if (process.env.VIEW_TIMINGS) console.log(JSON.stringify(all.map((t) => [t.extract, t.fetch, t.upload, t.draw].map(Math.round))));
    const median = (key) => {
      const v = all.map((t) => t[key]).sort((a, b) => a - b);
      return v[Math.floor(v.length / 2)];
    };
    await page.evaluate(() => { window.isocube.timings.length = 0; });
    return `extraction ${median("extract").toFixed(0)} ms, request ${median("fetch").toFixed(0)} ms, ` +
      `upload ${median("upload").toFixed(0)} ms, drawing ${median("draw").toFixed(0)} ms, ${(median("bytes") / 1e6).toFixed(1)} MB`;
  };
  await page.evaluate(() => { window.isocube.timings.length = 0; });
  const previews = await sweep(2000, 6000, 100, "latencies");
  console.log(`tangle:256, slider to the first picture (a preview on every k-th point, k = ${await page.evaluate(() => window.isocube.previewStride())}) over ${previews.length} levels: ${stats(previews)}`);
  console.log(`  previews: ${await breakdown(true)}`);
  const full = await sweep(3000, 5000, 500, "fullLatencies");
  console.log(`tangle:256, slider to the full surface (after 200 ms at rest) over ${full.length} levels: ${stats(full)}`);
  console.log(`  full surfaces: ${await breakdown(false)}`);
  await server.stop();
}

assert.deepEqual(errors, [], `errors on the page: ${errors.join("; ")}`);
await browser.close();
console.log("isocube view: browser test passed");
