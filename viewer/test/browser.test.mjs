// The page `mocodec view` writes, in headless Chromium (Debian's /usr/bin/chromium, driven by
// playwright-core; no browser is downloaded). Run by viewer/run_tests.sh, which makes the pages:
// MOCODEC_VIEW_PAGES holds <codec>.html (with originals), <codec>.json (the native runtime's
// poses and the encoder's errors), damaged.html and damaged.mcd; MOCODEC_VIEW_SHOTS, if set,
// receives the screenshots.
import { test, after } from "node:test";
import assert from "node:assert/strict";
import { existsSync, readdirSync, readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { chromium } from "playwright-core";

const PAGES = process.env.MOCODEC_VIEW_PAGES;
const SHOTS = process.env.MOCODEC_VIEW_SHOTS;
const CHROMIUM = process.env.CHROMIUM ?? "/usr/bin/chromium";
const POSE_TOLERANCE = 1e-5;
// The page measures in float32 positions what the encoder measured in float64.
const FIGURE_TOLERANCE_CM = 1e-3;

const codecs = PAGES && existsSync(PAGES)
  ? readdirSync(PAGES).filter((f) => f.endsWith(".json") && f !== "skipped.json").map((f) => f.slice(0, -5)).sort()
  : [];
if (!codecs.length) console.log(`!! SKIPPING the browser tests: MOCODEC_VIEW_PAGES=${PAGES ?? "(unset)"} holds no pages (viewer/run_tests.sh makes them)`);

const browser = codecs.length ? await chromium.launch({
  executablePath: CHROMIUM,
  // The flags the machine's closed network needs, and software WebGL (no GPU here).
  args: ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
}) : null;
after(() => browser?.close());

/** Open a page; collect console errors, page errors and every request that is not the file. */
async function open(file) {
  const page = await browser.newPage({ viewport: { width: 1400, height: 850 } });
  const problems = [];
  page.on("console", (m) => { if (m.type() === "error") problems.push(`console: ${m.text()}`); });
  page.on("pageerror", (e) => problems.push(`page error: ${e.message}`));
  page.on("request", (r) => { if (!/^(file|data|blob):/.test(r.url())) problems.push(`network: ${r.url()}`); });
  await page.goto(`file://${join(PAGES, file)}`);
  await page.waitForFunction(() => window.mocodecViewer?.state !== "loading" && window.mocodecViewer?.state !== undefined,
    null, { timeout: 30000 });
  return { page, problems };
}

const canvasShot = (page) => page.locator("#view").screenshot();

for (const codec of codecs) {
  const native = JSON.parse(readFileSync(join(PAGES, `${codec}.json`), "utf8"));

  test(`${codec}: the page opens with no console error and no network, and lists every clip`, async () => {
    const { page, problems } = await open(`${codec}.html`);
    assert.equal(await page.evaluate(() => mocodecViewer.state), "ready", await page.evaluate(() => mocodecViewer.error));
    const rows = await page.locator("#clips tbody tr").allTextContents();
    assert.equal(rows.length, native.clips.length);
    native.clips.forEach((c, i) => assert.ok(rows[i].startsWith(c.name), rows[i]));
    assert.deepEqual(problems, []);
    await page.close();
  });

  test(`${codec}: poses computed by the wasm in the page equal the native runtime's within ${POSE_TOLERANCE}`, async () => {
    const { page, problems } = await open(`${codec}.html`);
    const mine = await page.evaluate((poses) => poses.map((p) => mocodecViewer.pose(p.clip, p.time,
      { world: !!(p.flags & 1), loop: !!(p.flags & 2), nearest: !!(p.flags & 4) })), native.poses);
    let worst = 0;
    native.poses.forEach((p, k) => {
      assert.equal(mine[k].length, p.pose.length);
      p.pose.forEach((v, i) => { worst = Math.max(worst, Math.abs(v - mine[k][i])); });
    });
    console.log(`  ${codec}: ${native.poses.length} poses in the page, largest difference from native ${worst.toExponential(2)}`);
    assert.ok(worst <= POSE_TOLERANCE, `largest difference ${worst}`);
    assert.deepEqual(problems, []);
    await page.close();
  });

  test(`${codec}: the page's max / p99 / mean error per clip are the encoder's`, async () => {
    const { page } = await open(`${codec}.html`);
    for (const c of native.clips) {
      const figures = await page.evaluate((i) => { mocodecViewer.selectClip(i); return mocodecViewer.figures; }, c.index);
      const expected = native.errors[c.name];
      for (const key of ["max", "p99", "mean"]) {
        assert.ok(Math.abs(figures[key] - expected[key]) <= FIGURE_TOLERANCE_CM,
          `${c.name} ${key}: page ${figures[key]}, encoder ${expected[key]}`);
      }
      const shown = (await page.locator("#figures").textContent()).match(/max error([0-9.]+) cm/);
      assert.ok(shown && Math.abs(Number(shown[1]) - expected.max) < 1e-3, `figures panel: ${shown?.[0]}`);
    }
    await page.close();
  });
}

if (codecs.length) {
  const codec = codecs.includes("rma") ? "rma" : codecs[0];

  test(`${codec}: scrubbing the timeline (between frames too) moves the skeleton; play advances time`, async () => {
    const { page, problems } = await open(`${codec}.html`);
    const before = await canvasShot(page);
    const slider = page.locator("#scrub");
    const box = await slider.boundingBox();
    await page.mouse.click(box.x + box.width * 0.63, box.y + box.height / 2);
    const t = await page.evaluate(() => mocodecViewer.time);
    const clock = await page.locator("#clock").textContent();
    assert.ok(t > 0, `time after the click: ${t}`);
    assert.match(clock, /frame \d+\.\d\d/);
    const after = await canvasShot(page);
    assert.notDeepEqual(before, after, "the canvas did not change");
    // Between two frames: the pose lies between the poses of its frames (not on either).
    const between = await page.evaluate(() => {
      const c = mocodecViewer.clips()[0];
      const f = Math.floor(c.frameCount / 2);
      const at = (x) => mocodecViewer.pose(0, x / c.frameRate, { world: true });
      return { a: at(f), m: at(f + 0.5), b: at(f + 1) };
    });
    assert.notDeepEqual(between.m, between.a);
    assert.notDeepEqual(between.m, between.b);
    await page.locator("#play").click();
    await page.waitForTimeout(400);
    await page.locator("#play").click();
    assert.notEqual(await page.evaluate(() => mocodecViewer.time), t);
    await page.locator("#worst li").first().click();
    const worst = await page.evaluate(() => [mocodecViewer.time, mocodecViewer.figures.worstFrame, mocodecViewer.clips()[0].frameRate]);
    assert.ok(Math.abs(worst[0] * worst[2] - worst[1]) < 1e-3, `jumped to ${worst[0]} s`);
    await page.locator("#side-by-side").check();
    if (SHOTS) {
      await page.evaluate(() => mocodecViewer.setTime(0.45));
      writeFileSync(join(SHOTS, `viewer_${codec}.png`), await page.screenshot());
    }
    assert.deepEqual(problems, []);
    await page.close();
  });

  test("a damaged asset: the page says what is wrong, in words", async () => {
    const { page } = await open("damaged.html");
    assert.equal(await page.evaluate(() => mocodecViewer.state), "error");
    const box = page.locator("#error");
    assert.ok(await box.isVisible());
    const text = await box.textContent();
    assert.match(text, /Cannot open damaged\.mcd: checksum mismatch.* \(MCD_ERROR_CHECKSUM\)/);
    if (SHOTS) writeFileSync(join(SHOTS, "viewer_damaged.png"), await page.screenshot());
    await page.close();
  });

  test("opening a damaged .mcd from disk in a working page shows the error and keeps the clip", async () => {
    const { page } = await open(`${codec}.html`);
    await page.locator("#open").setInputFiles(join(PAGES, "damaged.mcd"));
    await page.waitForFunction(() => mocodecViewer.state === "error");
    assert.match(await page.locator("#error").textContent(), /checksum mismatch/);
    assert.equal((await page.evaluate(() => mocodecViewer.pose(0, 0.1, { world: true }))).length % 10, 0);
    await page.close();
  });
}
