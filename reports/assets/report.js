// clearfit report.html: loads the embedded heatmaps into <model-viewer>, the
// pressure / signal toggle, hotspot markers, and a snapshot for printing.
// The models are embedded as base64 and handed over as blob: URLs, because
// browsers refuse fetch() of file:// URLs (measured in Chromium: "Cross origin
// requests are only supported for protocol schemes ...").
(function () {
  'use strict';
  const data = JSON.parse(document.getElementById('clearfit-data').textContent);
  const viewer = document.getElementById('viewer');
  const status = { views: {}, current: null, loaded: false, error: null };
  window.clearfitReport = status;
  if (!viewer) return;

  const urls = {};
  for (const el of document.querySelectorAll('script.clearfit-model')) {
    const bin = atob(el.textContent.trim());
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; ++i) bytes[i] = bin.charCodeAt(i);
    urls[el.dataset.view] = URL.createObjectURL(new Blob([bytes], { type: 'model/gltf-binary' }));
  }

  viewer.addEventListener('load', () => {
    status.loaded = true;
    status.views[status.current] = 'loaded';
  });
  viewer.addEventListener('error', (event) => {
    status.error = (event.detail && event.detail.type) || 'error';
    status.views[status.current] = 'error';
  });

  function show(key) {
    if (!urls[key]) return;
    if (status.current !== key) {
      status.current = key;
      status.loaded = false;
      status.views[key] = 'loading';
      viewer.src = urls[key];
    }
    for (const b of document.querySelectorAll('.toggle button')) b.setAttribute('aria-pressed', String(b.dataset.view === key));
    for (const bar of document.querySelectorAll('.colorbar')) bar.hidden = bar.dataset.view !== key;
  }
  for (const b of document.querySelectorAll('.toggle button')) b.addEventListener('click', () => show(b.dataset.view));
  status.show = show;

  // Hotspots: a click shows the hotspot's numbers and highlights its table row.
  const panel = document.createElement('div');
  panel.className = 'hotspot-panel';
  panel.hidden = true;
  viewer.parentElement.appendChild(panel);
  function select(id) {
    for (const b of document.querySelectorAll('.hotspot')) b.classList.toggle('selected', b.dataset.hotspot === id);
    for (const r of document.querySelectorAll('#hotspot-table tbody tr')) r.classList.toggle('selected', r.dataset.hotspot === id);
    const info = document.querySelector('[data-hotspot-info="' + CSS.escape(id) + '"]');
    panel.hidden = !info;
    if (info) panel.replaceChildren(...Array.from(info.cloneNode(true).childNodes));
  }
  for (const b of document.querySelectorAll('.hotspot')) {
    b.addEventListener('click', (event) => { event.stopPropagation(); select(b.dataset.hotspot); });
  }
  for (const r of document.querySelectorAll('#hotspot-table tbody tr')) r.addEventListener('click', () => select(r.dataset.hotspot));
  status.select = select;

  // Hover: the values of the seen vertex nearest to the surface point under the pointer. data.vertices holds
  // the view's seen vertices as base64 little-endian float32 rows (x, y, z mm, kPa, kPa sigma, signal; NaN:
  // none) and their mesh ids (uint32); the hit point comes in the model's frame, the mesh's mm times
  // node_scale, as the hotspot markers' data-position.
  const decode = (b64, Type) => {
    const bin = atob(b64);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; ++i) bytes[i] = bin.charCodeAt(i);
    return new Type(bytes.buffer);
  };
  const vertices = data.vertices ? { ...data.vertices, rows: decode(data.vertices.rows, Float32Array), ids: decode(data.vertices.ids, Uint32Array) } : null;
  const tip = document.createElement('div');
  tip.className = 'vertex-tip';
  tip.hidden = true;
  viewer.parentElement.appendChild(tip);
  const fmt = (v, digits) => (v === null || v === undefined || Number.isNaN(v) ? '\u2014' : v.toFixed(digits));
  function vertexAt(clientX, clientY) {
    if (!vertices || !status.loaded) return null;
    const hit = viewer.positionAndNormalFromPoint(clientX, clientY);
    if (!hit) return null;
    const k = 1 / vertices.node_scale, p = [hit.position.x * k, hit.position.y * k, hit.position.z * k];
    const q = vertices.rows;
    let best = Infinity, index = -1;
    for (let i = 0; i < vertices.count; ++i) {
      const dx = q[6 * i] - p[0], dy = q[6 * i + 1] - p[1], dz = q[6 * i + 2] - p[2], d = dx * dx + dy * dy + dz * dz;
      if (d < best) { best = d; index = i; }
    }
    // Farther than the reach of the seen surface's own vertices: a part of the mesh the camera does not see.
    if (index < 0 || Math.sqrt(best) > vertices.reach_mm) return { unseen: true, point_mm: p };
    const v = { index, id: vertices.ids[index], point_mm: p, distance_mm: Math.sqrt(best), signal: q[6 * index + 5] };
    if (vertices.calibrated) { v.kpa = q[6 * index + 3]; v.kpa_sigma = q[6 * index + 4]; }
    return v;
  }
  // A pressure without a sigma is a bound: 0 kPa below detection, the calibration's top when saturated.
  function describe(v) {
    if (v.unseen) return 'not seen by the camera';
    let s = 'vertex ' + v.id + ': ';
    if ('kpa' in v) {
      if (Number.isNaN(v.kpa_sigma) && v.kpa === 0) s += 'below detection (0 kPa), ';
      else if (Number.isNaN(v.kpa_sigma) && v.kpa > 0) s += '\u2265 ' + fmt(v.kpa, 2) + ' kPa (saturated), ';
      else s += fmt(v.kpa, 2) + ' \u00b1 ' + fmt(v.kpa_sigma, 2) + ' kPa, ';
    }
    return s + 'signal ' + fmt(v.signal, 4);
  }
  // One lookup a frame, at the pointer's latest position (a move while a lookup waits replaces its point).
  let frame = 0, latest = null;
  viewer.addEventListener('pointermove', (moved) => {
    latest = moved;
    if (frame) return;
    frame = requestAnimationFrame(() => {
      frame = 0;
      const event = latest;
      const v = vertexAt(event.clientX, event.clientY);
      status.hovered = v;
      tip.hidden = !v;
      if (!v) return;
      tip.textContent = describe(v);
      const box = viewer.parentElement.getBoundingClientRect();
      tip.style.left = (event.clientX - box.left + 14) + 'px';
      tip.style.top = (event.clientY - box.top + 14) + 'px';
    });
  });
  viewer.addEventListener('pointerleave', () => { tip.hidden = true; status.hovered = null; });
  status.vertexAt = vertexAt;

  // Printing: a WebGL canvas does not print reliably, so print a snapshot of it.
  const snapshot = document.getElementById('viewer-print');
  const takeSnapshot = () => {
    if (status.loaded) snapshot.src = viewer.toDataURL('image/png');
  };
  window.addEventListener('beforeprint', takeSnapshot);
  window.matchMedia('print').addEventListener('change', (event) => { if (event.matches) takeSnapshot(); });

  const first = (data.views[0] || {}).key;
  if (first) show(first);
})();
