/* report.js - interactivity of the reflcheck report pages; plain JS, no network, no fetch API:
 * pages opened from disk (file://) get their data from script files only:
 *   window.REFLCHECK_IDS   (inline, every page: report_assets/ids.json, the element ids, data
 *                           attributes and layer names the pages use; none is spelled here)
 *   window.REFLCHECK_VIEW  (<scene>/view.js: linear float32 RGB images, base64)
 *   window.REFLCHECK_PAGE  (inline: comparisons and which view.js images they compare)
 * Load markers for headless tests, on <body>: data-loaded="n/total" (every <img> and every
 * image canvas that drew real data), data-failed="k", data-ready="1" once all are settled;
 * failures are listed in #load-errors (its section is shown only when there are any).
 */
(function () {
  'use strict';

  var NAMES = window.REFLCHECK_IDS, ID = NAMES.id, AT = NAMES.attr, LAYER = NAMES.layer;
  function el(key) { return document.getElementById(ID[key]); }
  function layerOf(cv) { return cv.getAttribute(AT.layer); }

  var load = { total: 0, loaded: 0, failed: 0, errors: [] };

  function markers() {
    var b = document.body;
    b.setAttribute(AT.loaded, load.loaded + '/' + load.total);
    b.setAttribute(AT.failed, String(load.failed));
    if (load.loaded + load.failed >= load.total) b.setAttribute(AT.ready, '1');
    var ul = el('loadErrors');
    if (!ul) return;
    ul.textContent = '';
    load.errors.forEach(function (m) {
      var li = document.createElement('li');
      li.textContent = m;
      ul.appendChild(li);
    });
    el('loadStatus').hidden = load.errors.length === 0;
  }
  function expect(n) { load.total += n; markers(); }
  function ok() { load.loaded++; markers(); }
  function fail(msg) { load.failed++; load.errors.push(msg); markers(); }

  function trackImages() {
    var imgs = Array.prototype.slice.call(document.querySelectorAll('img'));
    expect(imgs.length);
    imgs.forEach(function (img) {
      var done = false;
      function good() { if (!done) { done = true; ok(); } }
      function bad() { if (!done) { done = true; fail('image failed to load: ' + img.getAttribute('src')); } }
      if (img.complete) { if (img.naturalWidth > 0) good(); else bad(); }
      else { img.addEventListener('load', good); img.addEventListener('error', bad); }
    });
  }

  /* ---------------------------------------------------------------- index: filters */
  function initFilters() {
    var q = el('filterText');
    if (!q) return;
    var role = el('filterRole');
    var verdict = el('filterVerdict');
    var count = el('filterCount');
    var summary = Array.prototype.slice.call(document.querySelectorAll('#' + ID.summary + ' tbody tr'));
    var others = Array.prototype.slice.call(document.querySelectorAll('table.' + NAMES.cls.filterable + ':not(#' + ID.summary + ') tbody tr'));
    function apply() {
      var t = q.value.trim().toLowerCase(), r = role.value, v = verdict.value, shown = 0;
      summary.forEach(function (tr) {
        var vis = (!t || tr.textContent.toLowerCase().indexOf(t) >= 0) &&
          (!r || tr.getAttribute(AT.role) === r) && (!v || tr.getAttribute(AT.verdict) === v);
        tr.hidden = !vis;
        if (vis) shown++;
      });
      others.forEach(function (tr) {
        tr.hidden = !!t && tr.textContent.toLowerCase().indexOf(t) < 0;
      });
      count.textContent = shown + ' of ' + summary.length + ' comparisons shown';
    }
    q.addEventListener('input', apply);
    role.addEventListener('change', apply);
    verdict.addEventListener('change', apply);
    apply();
  }

  /* ---------------------------------------------------------------- scene page: viewer */
  function decodeFloats(b64, n, what) {
    var bin = atob(b64);
    if (bin.length !== n * 4) throw new Error(what + ': ' + bin.length + ' bytes, expected ' + n * 4);
    var u8 = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) u8[i] = bin.charCodeAt(i);
    /* view.js stores little-endian float32; DataView reads it so on any host. */
    var dv = new DataView(u8.buffer), out = new Float32Array(n);
    for (i = 0; i < n; i++) out[i] = dv.getFloat32(i * 4, true);
    return out;
  }

  function toDisplay(v) {
    if (v <= 0) return 0;
    if (v >= 1) return 255;
    var e = v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055;
    return Math.round(e * 255);
  }

  /* viridis, 9 anchors: perceptually ordered and readable for colour-blind viewers. */
  var VIRIDIS = [[68, 1, 84], [71, 45, 123], [59, 82, 139], [44, 114, 142], [33, 145, 140],
    [40, 174, 128], [94, 201, 98], [173, 220, 48], [253, 231, 37]];
  var HEAT_LO = -5, HEAT_HI = 0;
  function viridis(t) {
    t = Math.max(0, Math.min(1, t)) * (VIRIDIS.length - 1);
    var i = Math.min(VIRIDIS.length - 2, Math.floor(t)), f = t - i, a = VIRIDIS[i], b = VIRIDIS[i + 1];
    return [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f];
  }
  function heatT(e) {
    if (!(e > 0)) return 0;
    return (Math.log(e) / Math.LN10 - HEAT_LO) / (HEAT_HI - HEAT_LO);
  }

  function relError(t, r, n) {
    /* same denominator as the compare step (compare.h COMPARE_REL_EPS = 1e-8) */
    var out = new Float32Array(n);
    for (var i = 0; i < n; i++) {
      var m = 0;
      for (var c = 0; c < 3; c++) {
        var rv = r[3 * i + c], d = Math.abs(t[3 * i + c] - rv) / Math.sqrt(rv * rv + 1e-8);
        if (d !== d || d === Infinity) { m = NaN; break; }
        if (d > m) m = d;
      }
      out[i] = m;
    }
    return out;
  }

  function fmt(v) {
    if (v === undefined || v === null) return '—';
    if (v !== v) return 'NaN';
    if (v === 0) return '0';
    var a = Math.abs(v);
    if (a >= 1e-3 && a < 1e4) return v.toPrecision(5);
    return v.toExponential(3);
  }

  function drawLegend() {
    var cv = el('heatLegend');
    if (!cv) return;
    var ctx = cv.getContext('2d'), x0 = 10, w = cv.width - 20, h = 14;
    for (var x = 0; x < w; x++) {
      var c = viridis(x / (w - 1));
      ctx.fillStyle = 'rgb(' + Math.round(c[0]) + ',' + Math.round(c[1]) + ',' + Math.round(c[2]) + ')';
      ctx.fillRect(x0 + x, 2, 1, h);
    }
    ctx.strokeStyle = '#424a53';
    ctx.strokeRect(x0 - 0.5, 1.5, w + 1, h + 1);
    ctx.fillStyle = '#1f2328';
    ctx.font = '11px ui-monospace, "DejaVu Sans Mono", monospace';
    ctx.textAlign = 'center';
    var labels = ['≤1e-5', '1e-4', '1e-3', '1e-2', '1e-1', '≥1'];
    for (var k = 0; k <= 5; k++) {
      var px = x0 + Math.round(k * (w - 1) / 5) + 0.5;
      ctx.beginPath(); ctx.moveTo(px, 2 + h); ctx.lineTo(px, 6 + h); ctx.stroke();
      ctx.textAlign = k === 0 ? 'left' : (k === 5 ? 'right' : 'center');
      ctx.fillText(labels[k], k === 0 ? x0 : (k === 5 ? x0 + w : px), 18 + h);
    }
    ctx.textAlign = 'left';
  }

  function initScene() {
    var P = window.REFLCHECK_PAGE, V = window.REFLCHECK_VIEW;
    var views = Array.prototype.slice.call(document.querySelectorAll('canvas.' + NAMES.cls.view));
    expect(views.length);
    drawLegend();
    if (!P) { views.forEach(function () { fail('page data (REFLCHECK_PAGE) missing'); }); return; }
    if (!V) {
      views.forEach(function (cv) { fail(layerOf(cv) + ': ' + P.view_src + ' did not load'); });
      return;
    }
    var W = V.width, H = V.height, N = W * H, img = {}, decodeErr = {};
    Object.keys(V.images || {}).forEach(function (k) {
      try { img[k] = decodeFloats(V.images[k], N * 3, k); } catch (e) { decodeErr[k] = e.message; }
    });
    function aux(key) {
      if (!V[key]) return null;
      try { return decodeFloats(V[key], N, key); } catch (e) { fail(P.view_src + ': ' + e.message); return null; }
    }
    var ndotv = aux('ndotv'), coverage = aux('coverage');

    function offscreen() { var c = document.createElement('canvas'); c.width = W; c.height = H; return c; }
    var offImg = {}, offHeat = {}, rel = {};
    Object.keys(img).forEach(function (k) { offImg[k] = offscreen(); });
    P.comparisons.forEach(function (c) {
      if (img[c.testKey] && img[c.refKey]) { rel[c.id] = relError(img[c.testKey], img[c.refKey], N); offHeat[c.id] = offscreen(); }
    });

    var evInput = el('ev'), evLabel = el('evLabel');
    function renderImages() {
      var ev = parseFloat(evInput.value), k = Math.pow(2, ev);
      evLabel.textContent = 'EV ' + (ev >= 0 ? '+' : '') + ev.toFixed(2) + ' (×' + k.toPrecision(3) + ')';
      Object.keys(offImg).forEach(function (name) {
        var src = img[name], ctx = offImg[name].getContext('2d'), id = ctx.createImageData(W, H), d = id.data;
        for (var i = 0; i < N; i++) {
          var r = src[3 * i], g = src[3 * i + 1], b = src[3 * i + 2];
          if (!isFinite(r) || !isFinite(g) || !isFinite(b)) { d[4 * i] = 255; d[4 * i + 1] = 0; d[4 * i + 2] = 255; }
          else { d[4 * i] = toDisplay(r * k); d[4 * i + 1] = toDisplay(g * k); d[4 * i + 2] = toDisplay(b * k); }
          d[4 * i + 3] = 255;
        }
        ctx.putImageData(id, 0, 0);
      });
    }
    var maskInput = el('maskBg');
    function renderHeat() {
      var mask = maskInput && maskInput.checked && coverage;
      Object.keys(offHeat).forEach(function (cid) {
        var e = rel[cid], ctx = offHeat[cid].getContext('2d'), id = ctx.createImageData(W, H), d = id.data;
        for (var i = 0; i < N; i++) {
          var c;
          if (mask && !(coverage[i] > 0)) c = [48, 54, 61];
          else if (e[i] !== e[i]) c = [255, 0, 255];
          else c = viridis(heatT(e[i]));
          d[4 * i] = c[0]; d[4 * i + 1] = c[1]; d[4 * i + 2] = c[2]; d[4 * i + 3] = 255;
        }
        ctx.putImageData(id, 0, 0);
      });
    }

    var cw = views.length ? views[0].width : 360;
    var st = { fit: cw / W, s: cw / W, ox: 0, oy: 0, px: -1, py: -1, hover: false, toggled: false, drag: null };
    var selA = el('flipA'), selB = el('flipB');
    var flipMode = el('flipMode'), flipShown = el('flipShown');
    if (selB && selB.options.length > 1) selB.selectedIndex = 1;
    function flipImage() {
      if (!selA) return null;
      var showB = flipMode.value === 'hover' ? st.hover : st.toggled;
      return showB ? selB.value : selA.value;
    }
    function source(cv) {
      var l = layerOf(cv);
      if (l === LAYER.flip) return offImg[flipImage()] || null;
      if (l.indexOf(LAYER.image) === 0) return offImg[l.slice(LAYER.image.length)] || null;
      if (l.indexOf(LAYER.heat) === 0) return offHeat[l.slice(LAYER.heat.length)] || null;
      return null;
    }
    function draw(cv) {
      var ctx = cv.getContext('2d'), src = source(cv);
      ctx.setTransform(1, 0, 0, 1, 0, 0);
      ctx.fillStyle = '#1b1f24';
      ctx.fillRect(0, 0, cv.width, cv.height);
      if (!src) return false;
      ctx.imageSmoothingEnabled = false;
      ctx.setTransform(st.s, 0, 0, st.s, st.ox, st.oy);
      ctx.drawImage(src, 0, 0);
      ctx.setTransform(1, 0, 0, 1, 0, 0);
      if (st.px >= 0) {
        var x = st.ox + st.px * st.s, y = st.oy + st.py * st.s, w = Math.max(st.s, 3);
        /* black under white: visible on any image and on every heatmap colour */
        ctx.strokeStyle = '#000'; ctx.lineWidth = 3;
        ctx.strokeRect(x - 1.5, y - 1.5, w + 3, w + 3);
        ctx.strokeStyle = '#fff'; ctx.lineWidth = 1;
        ctx.strokeRect(x - 1.5, y - 1.5, w + 3, w + 3);
      }
      return true;
    }
    function drawAll() {
      views.forEach(draw);
      if (flipShown) flipShown.textContent = (flipImage() || '') + (flipImage() === (selB && selB.value) ? ' (B)' : ' (A)');
    }

    var probe = el('probe'), probeXY = el('probeXY');
    function updateProbe() {
      if (!probe) return;
      var x = st.px, y = st.py;
      probe.textContent = '';
      if (x < 0) { probeXY.textContent = ''; return; }
      var i = y * W + x;
      probeXY.textContent = '(' + x + ', ' + y + ')';
      /* cells as text, never markup: image names and comparison ids come from the run's files */
      function row(tag, cells, span) {
        var tr = document.createElement('tr');
        cells.forEach(function (t, k) {
          var td = document.createElement(tag);
          td.textContent = t;
          if (span && k === 1) td.colSpan = 3;
          tr.appendChild(td);
        });
        probe.appendChild(tr);
      }
      row('th', ['image', 'R', 'G', 'B']);
      Object.keys(img).forEach(function (k) {
        var a = img[k];
        row('td', [k, fmt(a[3 * i]), fmt(a[3 * i + 1]), fmt(a[3 * i + 2])]);
      });
      row('td', ['N·V', ndotv ? fmt(ndotv[i]) : '—'], true);
      row('td', ['coverage', coverage ? fmt(coverage[i]) : '—'], true);
      P.comparisons.forEach(function (c) {
        if (rel[c.id]) row('td', ['rel err ' + c.id, fmt(rel[c.id][i])], true);
      });
    }
    function pixelAt(cv, ev) {
      var r = cv.getBoundingClientRect();
      var mx = (ev.clientX - r.left) * cv.width / r.width, my = (ev.clientY - r.top) * cv.height / r.height;
      return { mx: mx, my: my, x: Math.floor((mx - st.ox) / st.s), y: Math.floor((my - st.oy) / st.s) };
    }
    function reset() { st.s = st.fit; st.ox = 0; st.oy = 0; drawAll(); }
    views.forEach(function (cv) {
      cv.addEventListener('wheel', function (ev) {
        ev.preventDefault();
        var p = pixelAt(cv, ev), f = ev.deltaY < 0 ? 1.25 : 0.8;
        var ns = Math.max(st.fit / 4, Math.min(st.fit * 512, st.s * f));
        f = ns / st.s;
        st.ox = p.mx - (p.mx - st.ox) * f; st.oy = p.my - (p.my - st.oy) * f; st.s = ns;
        drawAll();
      }, { passive: false });
      cv.addEventListener('mousedown', function (ev) { st.drag = { x: ev.clientX, y: ev.clientY }; ev.preventDefault(); });
      cv.addEventListener('mousemove', function (ev) {
        if (st.drag) {
          var r = cv.getBoundingClientRect(), sc = cv.width / r.width;
          st.ox += (ev.clientX - st.drag.x) * sc; st.oy += (ev.clientY - st.drag.y) * sc;
          st.drag = { x: ev.clientX, y: ev.clientY };
        }
        var p = pixelAt(cv, ev);
        if (p.x >= 0 && p.y >= 0 && p.x < W && p.y < H) { st.px = p.x; st.py = p.y; updateProbe(); }
        drawAll();
      });
      cv.addEventListener('dblclick', reset);
      if (layerOf(cv) === LAYER.flip) {
        cv.addEventListener('mouseenter', function () { st.hover = true; drawAll(); });
        cv.addEventListener('mouseleave', function () { st.hover = false; drawAll(); });
      }
    });
    window.addEventListener('mouseup', function () { st.drag = null; });
    document.addEventListener('keydown', function (ev) {
      if (ev.target && /INPUT|SELECT/.test(ev.target.tagName) && ev.target.type !== 'range') return;
      if (ev.key === 'f' || ev.key === 'F') { st.toggled = !st.toggled; if (flipMode) flipMode.value = 'toggle'; drawAll(); }
    });
    evInput.addEventListener('input', function () { renderImages(); drawAll(); });
    el('evReset').addEventListener('click', function () { evInput.value = '0'; renderImages(); drawAll(); });
    el('viewReset').addEventListener('click', reset);
    if (maskInput) maskInput.addEventListener('change', function () { renderHeat(); drawAll(); });
    [selA, selB, flipMode].forEach(function (s) { if (s) s.addEventListener('change', drawAll); });
    var tog = el('flipToggle');
    if (tog) tog.addEventListener('click', function () { st.toggled = !st.toggled; flipMode.value = 'toggle'; drawAll(); });

    renderImages();
    renderHeat();
    /* probe the centre pixel until the mouse picks another, so the table is never empty */
    st.px = Math.floor(W / 2); st.py = Math.floor(H / 2);
    updateProbe();
    views.forEach(function (cv) {
      var l = layerOf(cv);
      if (draw(cv)) { ok(); return; }
      var name = l.indexOf(':') > 0 ? l.slice(l.indexOf(':') + 1) : l;
      fail(l + ': no data' + (decodeErr[name] ? ' (' + decodeErr[name] + ')' : ' in ' + P.view_src));
    });
    drawAll();
  }

  function init() {
    var kind = document.body.getAttribute(AT.page);
    markers();
    trackImages();
    if (kind === NAMES.page.index) initFilters();
    if (kind === NAMES.page.scene) {
      try { initScene(); } catch (e) { fail('viewer: ' + e.message); }
    }
  }
  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', init);
  else init();
})();
