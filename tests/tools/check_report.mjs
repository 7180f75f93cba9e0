#!/usr/bin/env node
// Checks a clearfit report.html in a real headless browser (Debian's chromium
// driven by playwright-core from web/node_modules):
//  - it loads from file:// with no console error, no page error and no request
//    other than file:, data: and blob: URLs (http(s) requests are also blocked);
//  - every 3D view (pressure, signal) loads and renders: a screenshot of the
//    viewer is not blank (luminance spread and share of non-background pixels),
//    and the views differ from each other;
//  - the hotspot table equals report.json (exact values in data-value, shown
//    text rounded), and clicking a hotspot marker shows that hotspot's numbers;
//  - pointing at the surface shows the nearest seen vertex's kPa ± σ and signal ("below detection" or
//    "≥ … (saturated)" where the vertex has no σ);
//  - each view shows the colours its colour bar promises: the colour of the top of the range reached by the
//    seen vertices appears, and every hotspot marker stands beside its place: the marker's box does not hold
//    the place's centre, where the screenshot shows a colour of the colour bar (with a calibration, at least
//    0.8 of the place's lowest threshold in the pressure view) for a place of 1 mm² or more, not the marker.
// Usage: node check_report.mjs REPORT.html [--screenshot-dir DIR] [--timeout-ms 60000]
// Prints one JSON line of measurements; exits 1 with a message per failed check.
import { readFileSync, mkdirSync, writeFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { dirname, resolve, join } from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const webDir = process.env.CLEARFIT_WEB_DIR || resolve(here, '../../web');
const require = createRequire(join(webDir, 'package.json'));
const { chromium } = require('playwright-core');

const args = process.argv.slice(2);
const htmlPath = resolve(args[0] || '');
const opt = (name, fallback) => { const i = args.indexOf(name); return i >= 0 ? args[i + 1] : fallback; };
const shotDir = opt('--screenshot-dir', '');
const timeout = Number(opt('--timeout-ms', '60000'));
const executablePath = process.env.CLEARFIT_CHROMIUM || '/usr/bin/chromium';

const failures = [];
const fail = (msg) => failures.push(msg);
const measured = { html: htmlPath, views: {} };

const report = JSON.parse(readFileSync(join(dirname(htmlPath), 'report.json'), 'utf8'));

const browser = await chromium.launch({
  executablePath,
  args: ['--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--disable-background-networking',
         '--disable-component-update', '--disable-sync', '--no-first-run', '--disable-quic'],
});
try {
  const context = await browser.newContext({ viewport: { width: 1200, height: 900 } });
  await context.route(/^https?:/, (route) => route.abort());
  const page = await context.newPage();
  page.on('console', (m) => { if (m.type() === 'error') fail(`console error: ${m.text()}`); });
  page.on('pageerror', (e) => fail(`page error: ${e.message}`));
  page.on('dialog', (d) => { fail(`a dialog opened (injected script?): ${d.message()}`); d.dismiss().catch(() => {}); });
  page.on('request', (r) => {
    const url = r.url();
    if (!/^(file|data|blob):/.test(url)) fail(`network request: ${url}`);
  });

  const t0 = Date.now();
  await page.goto(pathToFileURL(htmlPath).href, { waitUntil: 'load', timeout });
  measured.page_load_ms = Date.now() - t0;

  // A PNG's pixels (RGBA rows), decoded in the page through a canvas. They come back as one base64 string:
  // returned as an array of numbers (2 million for a 1060 x 481 view) they took 20-30 s to serialise.
  const pixels = async (png) => {
    const img = await page.evaluate(async (b64) => {
      const img = new Image();
      img.src = 'data:image/png;base64,' + b64;
      await img.decode();
      const c = document.createElement('canvas');
      c.width = img.width; c.height = img.height;
      const g = c.getContext('2d');
      g.drawImage(img, 0, 0);
      const bytes = g.getImageData(0, 0, c.width, c.height).data;
      let binary = '';
      for (let i = 0; i < bytes.length; i += 0x8000) binary += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
      return { width: c.width, height: c.height, rgba: btoa(binary) };
    }, png.toString('base64'));
    return { width: img.width, height: img.height, data: new Uint8Array(Buffer.from(img.rgba, 'base64')) };
  };
  // Luminance spread and share of pixels unlike the background (top-left pixel) of decoded pixels.
  const pixelStats = (img) => {
    const d = img.data;
    const bg = [d[0], d[1], d[2]];
    let n = 0, sum = 0, sum2 = 0, differ = 0, colourful = 0;
    for (let i = 0; i < d.length; i += 4) {
      const y = 0.2126 * d[i] + 0.7152 * d[i + 1] + 0.0722 * d[i + 2];
      sum += y; sum2 += y * y; ++n;
      if (Math.abs(d[i] - bg[0]) + Math.abs(d[i + 1] - bg[1]) + Math.abs(d[i + 2] - bg[2]) > 30) ++differ;
      if (Math.max(d[i], d[i + 1], d[i + 2]) - Math.min(d[i], d[i + 1], d[i + 2]) > 60) ++colourful;
    }
    const mean = sum / n;
    return { luminance_std: Math.sqrt(Math.max(0, sum2 / n - mean * mean)), foreground_fraction: differ / n, colourful_fraction: colourful / n };
  };

  // The colour bar of a view as 256 sRGB samples over [lo, hi] (its CSS gradient's stops).
  const ramp = (key) => page.evaluate((k) => {
    const bar = document.querySelector(`.colorbar[data-view="${k}"]`);
    if (!bar) return null;
    const css = bar.querySelector('.colorbar-ramp').getAttribute('style');
    const stops = Array.from(css.matchAll(/#([0-9a-f]{6}) ([0-9.]+)%/g)).map((m) => ({
      rgb: [0, 2, 4].map((i) => parseInt(m[1].substr(i, 2), 16)), at: Number(m[2]) / 100 }));
    const samples = [];
    for (let i = 0; i < 256; ++i) {
      const t = i / 255;
      let k2 = 1;
      while (k2 < stops.length - 1 && stops[k2].at < t) ++k2;
      const a = stops[k2 - 1], b = stops[k2], w = b.at > a.at ? (t - a.at) / (b.at - a.at) : 0;
      samples.push(a.rgb.map((c, j) => c + w * (b.rgb[j] - c)));
    }
    return { lo: Number(bar.dataset.lo), hi: Number(bar.dataset.hi), samples };
  }, key);
  // The value of the colour-bar colour nearest to rgb, and how far (RGB distance) the colour is from it.
  // Remembered per bar and colour: a view has a few thousand distinct colours in half a million pixels.
  const onRampSeen = new WeakMap();
  const onRamp = (bar, rgb) => {
    if (!onRampSeen.has(bar)) onRampSeen.set(bar, new Map());
    const seen = onRampSeen.get(bar), colour = `${rgb[0]},${rgb[1]},${rgb[2]}`;
    if (!seen.has(colour)) seen.set(colour, nearestOnRamp(bar, rgb));
    return seen.get(colour);
  };
  const nearestOnRamp = (bar, rgb) => {
    let best = Infinity, index = 0;
    bar.samples.forEach((c, i) => {
      const d = (c[0] - rgb[0]) ** 2 + (c[1] - rgb[1]) ** 2 + (c[2] - rgb[2]) ** 2;
      if (d < best) { best = d; index = i; }
    });
    return { value: bar.lo + (bar.hi - bar.lo) * index / 255, distance: Math.sqrt(best) };
  };
  const embeddedVertices = await page.evaluate(() => JSON.parse(document.getElementById('clearfit-data').textContent).vertices || null);
  const vertexRows = embeddedVertices ? new Float32Array(new Uint8Array(Buffer.from(embeddedVertices.rows, 'base64')).buffer) : null;
  const calibratedReport = Boolean(report.calibration && report.calibration.pressure);

  async function checkColours(key, img) {
    const bar = await ramp(key);
    if (!bar) { fail(`view ${key}: no colour bar`); return; }
    const rgbAt = (x, y) => { const i = 4 * (Math.round(y) * img.width + Math.round(x)); return img.data.slice(i, i + 3); };
    // The top of the range the seen vertices reach (kPa in the pressure view, else the signal), within the bar.
    const column = key === 'pressure' ? 3 : 5;
    let top = -Infinity;
    if (vertexRows) for (let i = column; i < vertexRows.length; i += 6) if (Number.isFinite(vertexRows[i])) top = Math.max(top, vertexRows[i]);
    top = Math.min(top, bar.hi);
    const high = bar.lo + 0.8 * (top - bar.lo);
    let highPixels = 0;
    for (let i = 0; i < img.data.length; i += 4) {
      const r = onRamp(bar, [img.data[i], img.data[i + 1], img.data[i + 2]]);
      if (r.distance < 12 && r.value >= high) ++highPixels;
    }
    measured.views[key].top_value = top;
    measured.views[key].pixels_at_top = highPixels;
    if (Number.isFinite(top) && top > bar.lo && highPixels < 5)
      fail(`view ${key}: the colour of ${high.toFixed(3)} and above (0.8 of the top the seen vertices reach, ${top.toFixed(3)}) shows on ${highPixels} pixels`);
    // Markers beside their places: the place's centre, projected by model-viewer (a probe hotspot there), lies
    // outside its marker's box and shows a colour of the bar.
    const centres = await page.evaluate(async () => {
      const viewer = document.getElementById('viewer');
      const probes = [];
      for (const b of document.querySelectorAll('button.hotspot[data-centroid]')) {
        const probe = document.createElement('div');
        probe.slot = 'hotspot-probe-' + b.dataset.hotspot;
        probe.dataset.position = b.dataset.centroid;
        probe.style.cssText = 'width:0;height:0;pointer-events:none';
        viewer.appendChild(probe);
        probes.push([b, probe]);
      }
      await new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)));
      const box = viewer.getBoundingClientRect();
      const out = probes.map(([b, probe]) => {
        const q = viewer.queryHotspot(probe.slot);
        const m = b.getBoundingClientRect();
        return { id: b.dataset.hotspot, centre: q ? [q.canvasPosition.x, q.canvasPosition.y] : null,
                 marker: [m.left - box.left, m.top - box.top, m.right - box.left, m.bottom - box.top] };
      });
      for (const [, probe] of probes) probe.remove();
      return out;
    });
    measured.views[key].markers = [];
    for (const c of centres) {
      const h = (report.hotspots || []).find((x) => String(x.id) === c.id) || {};
      if (!c.centre) { fail(`view ${key}: the centre of place ${c.id} could not be projected`); continue; }
      const [x, y] = c.centre, [l, t, r, b] = c.marker;
      const covered = x >= l - 2 && x <= r + 2 && y >= t - 2 && y <= b + 2;
      const colour = onRamp(bar, rgbAt(x, y));
      measured.views[key].markers.push({ id: c.id, centre: [Math.round(x), Math.round(y)], marker: c.marker.map(Math.round), value: colour.value, distance: colour.distance });
      if (covered) fail(`view ${key}: the marker of place ${c.id} covers its centre (${x.toFixed(0)}, ${y.toFixed(0)})`);
      // The colour at the centre, for places of 1 mm² and more (a smaller one is a few pixels across, and may
      // lie beside unseen skin). Within 40 of the bar: vertex colours blend across a coarse mesh's triangles
      // off the bar's curve, while the marker (red, white), the no-data grey and the background lie 100 and
      // more from it.
      if (covered || !(h.area_mm2 >= 1)) continue;
      if (!(colour.distance < 40)) fail(`view ${key}: the centre of place ${c.id} shows rgb ${rgbAt(x, y).join(',')}, no colour of the bar`);
      const threshold = h.levels && h.levels[0] ? h.levels[0].threshold_kpa : undefined;
      if (key === 'pressure' && calibratedReport && Number.isFinite(threshold) && colour.value < 0.8 * threshold)
        fail(`view ${key}: the centre of place ${c.id} shows ${colour.value.toFixed(2)} kPa, under 0.8 of its threshold ${threshold}`);
    }
  }

  const views = await page.evaluate(() => JSON.parse(document.getElementById('clearfit-data').textContent).views.map((v) => v.key));
  const shots = {};
  for (const key of views) {
    const t1 = Date.now();
    await page.evaluate((k) => window.clearfitReport.show(k), key);
    try {
      await page.waitForFunction((k) => window.clearfitReport.current === k &&
                                        ['loaded', 'error'].includes(window.clearfitReport.views[k]),
                                 key, { timeout });
    } catch (e) {
      fail(`view ${key}: the model did not load within ${timeout} ms`);
      continue;
    }
    const state = await page.evaluate(() => ({ error: window.clearfitReport.error, visible: document.getElementById('viewer').modelIsVisible }));
    if (state.error) fail(`view ${key}: model-viewer reported ${state.error}`);
    // Let the renderer draw a few frames after the load event.
    await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(() => setTimeout(r, 300)))));
    const png = await page.locator('#viewer').screenshot();
    shots[key] = png.toString('base64');
    if (shotDir) { mkdirSync(shotDir, { recursive: true }); writeFileSync(join(shotDir, `view_${key}.png`), png); }
    const img = await pixels(png);
    const stats = pixelStats(img);
    measured.views[key] = { load_ms: Date.now() - t1, model_visible: state.visible, ...stats };
    await checkColours(key, img);
    // Not blank: the part stands out from the background, and the heatmap's
    // colours (saturated, unlike the grey no-data colour and the background) show.
    if (!(stats.luminance_std > 8 && stats.foreground_fraction > 0.02 && stats.colourful_fraction > 0.01))
      fail(`view ${key}: the 3D view looks blank (luminance std ${stats.luminance_std.toFixed(1)}, ` +
           `${(100 * stats.foreground_fraction).toFixed(2)} % of pixels unlike the background, ` +
           `${(100 * stats.colourful_fraction).toFixed(2)} % coloured)`);
  }
  if (views.length > 1 && shots[views[0]] && shots[views[0]] === shots[views[1]]) fail('the pressure and signal views look identical');

  // The hotspot table against report.json.
  const rows = await page.$$eval('#hotspot-table tbody tr', (trs) => trs.map((tr) => ({
    id: tr.dataset.hotspot,
    cells: Object.fromEntries(Array.from(tr.querySelectorAll('td[data-key]')).map((td) => [td.dataset.key, { value: td.dataset.value, text: td.textContent }])),
  })));
  const hotspots = report.hotspots || [];
  measured.hotspot_rows = rows.length;
  if (rows.length !== hotspots.length) fail(`hotspot table has ${rows.length} rows, report.json ${hotspots.length} hotspots`);
  const calibrated = Boolean(report.calibration && report.calibration.pressure);
  const digits = calibrated
    ? { peak_kpa: 2, peak_sigma_kpa: 2, mean_kpa: 2, mean_sigma_kpa: 2 }
    : { peak_signal: 4, mean_signal: 4 };
  const shown = (v, d) => (v === null || v === undefined ? '\u2014' : v.toFixed(d));
  hotspots.forEach((h, i) => {
    const row = rows[i];
    if (!row) return;
    if (String(h.id) !== row.id) fail(`row ${i}: id ${row.id}, report.json ${h.id}`);
    for (const [key, d] of Object.entries(digits)) {
      const cell = row.cells[key];
      if (!cell) { fail(`hotspot ${h.id}: no ${key} column`); continue; }
      const value = cell.value === '' ? null : JSON.parse(cell.value);
      if (value !== (h[key] ?? null)) fail(`hotspot ${h.id} ${key}: data-value ${cell.value}, report.json ${h[key]}`);
      if (cell.text !== shown(h[key] ?? null, d)) fail(`hotspot ${h.id} ${key}: shows "${cell.text}", expected "${shown(h[key] ?? null, d)}"`);
    }
    if (JSON.stringify(JSON.parse(row.cells.centroid_mm.value)) !== JSON.stringify(h.centroid_mm)) fail(`hotspot ${h.id}: centroid differs`);
    // One row per place: its area at each threshold (levels) in a column of its own.
    (h.levels || []).forEach((level, l) => {
      const cell = row.cells[`area_mm2_${l}`];
      if (!cell) { fail(`hotspot ${h.id}: no area column for level ${l}`); return; }
      if (JSON.parse(cell.value) !== level.area_mm2) fail(`hotspot ${h.id} level ${l}: area ${cell.value}, report.json ${level.area_mm2}`);
      if (!cell.text.startsWith(shown(level.area_mm2, 1))) fail(`hotspot ${h.id} level ${l}: shows "${cell.text}"`);
    });
  });

  // A click on a marker shows its numbers.
  if (hotspots.length && views.length) {
    const id = String(hotspots[0].id);
    await page.locator(`button.hotspot[data-hotspot="${id}"]`).click({ force: true });
    const panel = await page.locator('.hotspot-panel').textContent();
    const visible = await page.locator('.hotspot-panel').isVisible();
    if (!visible || !panel.includes(`Hotspot ${id}`)) fail(`clicking hotspot ${id} did not show its numbers (panel: "${panel}")`);
    if (report.calibration.pressure && !panel.includes(hotspots[0].peak_kpa.toFixed(2))) fail(`hotspot ${id} panel lacks its peak ${hotspots[0].peak_kpa.toFixed(2)}`);
  }

  // Hover: a real pointer move over the surface shows the numbers of the seen vertex nearest to the point
  // under it. The point comes from model-viewer's own positionAndNormalFromPoint; the nearest vertex and its
  // numbers are found here from the page's embedded table (decoded in node), not through report.js.
  const embedded = await page.evaluate(() => JSON.parse(document.getElementById('clearfit-data').textContent).vertices || null);
  if (views.length && !embedded) fail('the page embeds no vertex table for the hover');
  if (views.length && embedded) {
    const rows = new Float32Array(new Uint8Array(Buffer.from(embedded.rows, 'base64')).buffer);
    const ids = new Uint32Array(new Uint8Array(Buffer.from(embedded.ids, 'base64')).buffer);
    if (rows.length !== 6 * embedded.count || ids.length !== embedded.count) fail(`vertex table: ${rows.length} floats and ${ids.length} ids for ${embedded.count} vertices`);
    const nearest = (p) => {
      let best = Infinity, index = -1;
      for (let i = 0; i < embedded.count; ++i) {
        const d = (rows[6 * i] - p[0]) ** 2 + (rows[6 * i + 1] - p[1]) ** 2 + (rows[6 * i + 2] - p[2]) ** 2;
        if (d < best) { best = d; index = i; }
      }
      return { index, distance: Math.sqrt(best) };
    };
    const box = await page.locator('#viewer').boundingBox();
    // Of the points of a 11 x 11 grid over the view that lie on the seen surface, the one whose vertex shows
    // the most (kPa, or the signal without a calibration): the tip then shows numbers, not zeros.
    let target = null;
    const shows = (i) => (embedded.calibrated ? rows[6 * i + 3] : rows[6 * i + 5]);
    for (let gy = 1; gy < 12; ++gy)
      for (let gx = 1; gx < 12; ++gx) {
        const x = box.x + box.width * gx / 12, y = box.y + box.height * gy / 12;
        const hit = await page.evaluate(([px, py]) => {
          const h = document.getElementById('viewer').positionAndNormalFromPoint(px, py);
          return h ? [h.position.x, h.position.y, h.position.z] : null;
        }, [x, y]);
        if (!hit) continue;
        const p = hit.map((c) => c / embedded.node_scale);
        const n = nearest(p);
        // A point on the seen surface, not under a hotspot marker (the marker would take the pointer).
        const onMarker = await page.evaluate(([px, py]) => Boolean(document.elementFromPoint(px, py)?.closest?.('.hotspot')), [x, y]);
        if (n.distance <= embedded.reach_mm && !onMarker && (!target || shows(n.index) > shows(target.index))) target = { x, y, p, ...n };
      }
    if (!target) fail('no point of the 3D view lies on the seen surface');
    else {
      await page.mouse.move(target.x, target.y);
      // Wait for the lookup at this point (an earlier pointer move may have left one at another).
      await page.waitForFunction((q) => {
        const point = window.clearfitReport.hovered?.point_mm;
        return Boolean(point) && Math.hypot(point[0] - q[0], point[1] - q[1], point[2] - q[2]) < 0.5;
      }, target.p, { timeout }).catch(() => {});
      await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
      const tip = page.locator('.vertex-tip');
      const text = (await tip.isVisible()) ? await tip.textContent() : '';
      const i = target.index, row = rows.subarray(6 * i, 6 * i + 6);
      const shownValue = (v, d) => (Number.isNaN(v) ? '\u2014' : v.toFixed(d));
      const pressureText = Number.isNaN(row[4]) && row[3] === 0 ? 'below detection (0 kPa), '
                         : Number.isNaN(row[4]) && row[3] > 0 ? `\u2265 ${shownValue(row[3], 2)} kPa (saturated), `
                         : `${shownValue(row[3], 2)} \u00b1 ${shownValue(row[4], 2)} kPa, `;
      const expected = `vertex ${ids[i]}: ` + (embedded.calibrated ? pressureText : '') + `signal ${shownValue(row[5], 4)}`;
      measured.hover = { at: [Math.round(target.x), Math.round(target.y)], vertex: ids[i], distance_mm: target.distance, shown: text };
      if (text !== expected) fail(`hovering the surface shows "${text}", expected "${expected}"`);
    }
  }

  // Screen: the print snapshot stays hidden.
  if (views.length && await page.locator('#viewer-print').isVisible()) fail('the print snapshot of the 3D view shows on screen');

  // Print: the interactive controls are hidden.
  await page.emulateMedia({ media: 'print' });
  const printHidden = await page.evaluate(() => Array.from(document.querySelectorAll('model-viewer, .toggle, .hint')).every((e) => getComputedStyle(e).display === 'none'));
  if (!printHidden) fail('the print stylesheet does not hide the interactive viewer');
  if (shotDir) await page.screenshot({ path: join(shotDir, 'page.png'), fullPage: true });
} finally {
  await browser.close();
}

console.log(JSON.stringify(measured));
if (failures.length) {
  for (const f of failures) console.error('check_report: ' + f);
  process.exit(1);
}
