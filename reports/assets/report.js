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
