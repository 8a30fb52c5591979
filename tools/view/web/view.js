// exodaq view: draws the arm from `exodaq view`'s event stream (/events):
//   hello   model, view settings, trail, last frame/status/stream (on connect)
//   frame   one decimated joint state with every frame origin (m, O0)
//   status  the service's last status
//   stream  live / waiting / no-data / stopped, age, rate (at least 2 Hz)
// window.exodaqView.state() returns what was last drawn, for tests.
'use strict';

(function () {
  const COLOURS = {
    ok: '#2e9d48', unhomed: '#d08a00', held: '#b8a200', fault: '#d0312d',
    segment: '#3b4252', palm: '#1f6fd1', stale: '#a3a9b3', mismatch: '#d0312d',
    grid: '#eceef1', axis: '#c5cad3', text: '#4c566a',
  };
  // Three projections of O0 (z up): [horizontal axis, vertical axis].
  const VIEWS = [
    { id: 'front', title: 'front  x → , z ↑', h: 0, v: 2 },
    { id: 'side', title: 'side  y → , z ↑', h: 1, v: 2 },
    { id: 'top', title: 'top  x → , y ↑', h: 0, v: 1 },
  ];
  const QUIET_MS = 2500;  // no event at all for this long: the server is gone
  const RAD2DEG = 180 / Math.PI;

  const canvas = document.getElementById('arm');
  const ctx = canvas.getContext('2d');
  const $ = (id) => document.getElementById(id);

  const st = {
    connection: 'connecting',  // connecting | open | lost
    hello: null, frame: null, status: null, stream: null,
    trail: [],                 // [t, x, y, z]
    drawn: null,
    framesDrawn: 0,
    counts: { hello: 0, frame: 0, status: 0, stream: 0, errors: 0 },
    lastEventMs: 0,
  };

  // What the page shows as a whole: the connection first, then the stream.
  function display() {
    if (st.connection !== 'open') return st.hello ? 'disconnected' : 'connecting';
    return st.stream ? st.stream.state : 'waiting';
  }

  // ---- drawing ----------------------------------------------------------
  const W = 960, H = 340, PANEL = 320, PAD = 14;

  function setupCanvas() {
    const dpr = window.devicePixelRatio || 1;
    canvas.width = W * dpr;
    canvas.height = H * dpr;
    canvas.style.width = W + 'px';
    canvas.style.height = H + 'px';
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  }

  function scale() {
    const reach = st.hello && st.hello.model.reach_m > 0 ? st.hello.model.reach_m : 0.3;
    return (PANEL / 2 - PAD - 6) / (reach * 1.05);
  }

  // O0 point -> canvas pixel (CSS px) in panel k.
  function project(k, p) {
    const v = VIEWS[k], s = scale();
    const cx = k * PANEL + PANEL / 2, cy = PAD + (H - PAD) / 2;
    return [cx + p[v.h] * s, cy - p[v.v] * s];
  }

  function finite(p) { return p && p.every((x) => typeof x === 'number' && isFinite(x)); }

  function drawPanel(k) {
    const v = VIEWS[k], s = scale();
    const x0 = k * PANEL;
    const [ox, oy] = project(k, [0, 0, 0]);
    ctx.save();
    ctx.beginPath();
    ctx.rect(x0, 0, PANEL, H);
    ctx.clip();
    // 5 cm grid, axes through O0, the reach circle.
    ctx.strokeStyle = COLOURS.grid;
    ctx.lineWidth = 1;
    const step = 0.05 * s;
    for (let d = -6; d <= 6; d++) {
      ctx.beginPath(); ctx.moveTo(ox + d * step, 0); ctx.lineTo(ox + d * step, H); ctx.stroke();
      ctx.beginPath(); ctx.moveTo(x0, oy + d * step); ctx.lineTo(x0 + PANEL, oy + d * step); ctx.stroke();
    }
    ctx.strokeStyle = COLOURS.axis;
    ctx.beginPath(); ctx.moveTo(x0, oy); ctx.lineTo(x0 + PANEL, oy); ctx.stroke();
    ctx.beginPath(); ctx.moveTo(ox, 0); ctx.lineTo(ox, H); ctx.stroke();
    ctx.setLineDash([4, 4]);
    ctx.beginPath();
    ctx.arc(ox, oy, (st.hello ? st.hello.model.reach_m : 0.3) * s, 0, 2 * Math.PI);
    ctx.stroke();
    ctx.setLineDash([]);
    ctx.fillStyle = COLOURS.text;
    ctx.font = '12px system-ui, sans-serif';
    ctx.fillText(v.title, x0 + 8, 14);
    ctx.fillText('5 cm grid', x0 + PANEL - 64, H - 6);
    ctx.restore();
    ctx.strokeStyle = '#d8dbe0';
    ctx.beginPath(); ctx.moveTo(x0 + PANEL + 0.5, 0); ctx.lineTo(x0 + PANEL + 0.5, H); ctx.stroke();
  }

  function drawTrail(k, live) {
    const n = st.trail.length;
    if (n < 2) return;
    ctx.lineWidth = 2;
    for (let i = 1; i < n; i++) {
      const a = st.trail[i - 1], b = st.trail[i];
      if (!finite(a) || !finite(b)) continue;
      const alpha = 0.1 + 0.6 * (i / n);
      ctx.strokeStyle = live ? `rgba(31, 111, 209, ${alpha})` : `rgba(163, 169, 179, ${alpha})`;
      const [x1, y1] = project(k, a.slice(1));
      const [x2, y2] = project(k, b.slice(1));
      ctx.beginPath(); ctx.moveTo(x1, y1); ctx.lineTo(x2, y2); ctx.stroke();
    }
  }

  // The arm in panel k: segments between successive frame origins, joint i's
  // ring at frame i-1's origin (rings grow where origins coincide, as the four
  // shoulder joints do), the palm on top. Returns the pixels drawn.
  function drawArm(k, f, live) {
    const pts = f.frames.map((p) => (finite(p) ? project(k, p) : null));
    ctx.lineCap = 'round';
    ctx.strokeStyle = live ? COLOURS.segment : COLOURS.stale;
    ctx.lineWidth = 5;
    for (let i = 1; i < pts.length; i++) {
      if (!pts[i - 1] || !pts[i]) continue;
      ctx.beginPath(); ctx.moveTo(...pts[i - 1]); ctx.lineTo(...pts[i]); ctx.stroke();
    }
    const rings = [];
    for (let j = 0; j < f.class.length && j < pts.length; j++) {
      const p = pts[j];
      if (!p) continue;
      const same = rings.filter((r) => Math.hypot(r.p[0] - p[0], r.p[1] - p[1]) < 1).length;
      rings.push({ joint: j + 1, p, r: 7 + 4 * same,
        colour: live ? COLOURS[f.class[j]] || COLOURS.fault : COLOURS.stale });
    }
    ctx.lineWidth = 3;
    for (const r of rings) {
      ctx.strokeStyle = r.colour;
      ctx.beginPath(); ctx.arc(r.p[0], r.p[1], r.r, 0, 2 * Math.PI); ctx.stroke();
    }
    // The published palm, where it disagrees with the computed one (> 1 mm).
    if (f.published && f.fk_error_m !== null && f.fk_error_m > 1e-3 && finite(f.published.position)) {
      const [qx, qy] = project(k, f.published.position);
      ctx.strokeStyle = COLOURS.mismatch;
      ctx.lineWidth = 2;
      ctx.strokeRect(qx - 6, qy - 6, 12, 12);
    }
    const palm = finite(f.palm) ? project(k, f.palm) : null;
    if (palm) {
      ctx.fillStyle = live ? COLOURS.palm : COLOURS.stale;
      ctx.beginPath(); ctx.arc(palm[0], palm[1], 6, 0, 2 * Math.PI); ctx.fill();
    }
    return { frames: pts, palm, rings: rings.map((r) => ({ joint: r.joint, x: r.p[0], y: r.p[1], r: r.r, colour: r.colour })) };
  }

  function draw() {
    const live = display() === 'live';
    ctx.clearRect(0, 0, W, H);
    ctx.fillStyle = '#fff';
    ctx.fillRect(0, 0, W, H);
    const px = {}, palmPx = {}, rings = {};
    for (let k = 0; k < VIEWS.length; k++) {
      drawPanel(k);
      drawTrail(k, live);
      if (st.frame) {
        const d = drawArm(k, st.frame, live);
        px[VIEWS[k].id] = d.frames;
        palmPx[VIEWS[k].id] = d.palm;
        rings[VIEWS[k].id] = d.rings;
      }
    }
    if (!live) {
      ctx.fillStyle = 'rgba(29, 35, 43, 0.55)';
      ctx.font = 'bold 22px system-ui, sans-serif';
      ctx.textAlign = 'center';
      ctx.fillText(display().toUpperCase().replace('-', ' '), W / 2, H / 2 - 40);
      ctx.textAlign = 'start';
    }
    const f = st.frame;
    st.drawn = f ? {
      seq: f.seq, run_id: f.run_id, t: f.t, q: f.q, homed: f.homed, flags: f.flags, class: f.class,
      frames: f.frames, palm: f.palm, elbow: f.elbow, published: f.published,
      fk_error_m: f.fk_error_m, style: live ? 'live' : 'stale', px, palm_px: palmPx, rings,
    } : null;
    st.framesDrawn++;
  }

  // ---- text ---------------------------------------------------------------
  function fmt(x, digits) { return typeof x === 'number' && isFinite(x) ? x.toFixed(digits) : '–'; }
  function badge(el, text, cls) { el.textContent = text; el.className = 'badge ' + (cls || ''); }

  function bannerText() {
    const d = display(), s = st.stream, ch = (st.hello ? st.hello.view.prefix : '') + 'EXO_JOINT_STATE';
    switch (d) {
      case 'connecting': return 'Connecting to exodaq view…';
      case 'disconnected': return 'DISCONNECTED: the view server does not answer (is `exodaq view` still running?)';
      case 'waiting': return 'WAITING: no message on ' + ch + ' yet (is exodaqd running, with this URL and prefix?)';
      case 'live': return 'LIVE';
      case 'no-data': return 'NO DATA: ' + (s && s.reason ? s.reason : 'the stream stopped');
      case 'stopped': return 'STOPPED: ' + (s && s.reason ? s.reason : 'the service stopped');
      default: return d;
    }
  }

  function updateText() {
    const d = display(), b = $('banner');
    b.className = 'banner ' + d;
    b.textContent = bannerText();
    const h = st.hello, f = st.frame, s = st.status, sm = st.stream;
    const rig = (s && s.rig) || (h && h.view.rig) || '';
    $('rig').textContent = rig || '–';
    // Several rigs, several tabs: each tab's title names its rig.
    document.title = rig ? `exodaq view — ${rig}` : 'exodaq view';
    $('run').textContent = (f && f.run_id) || (s && s.run_id) || '–';
    $('seq').textContent = f ? String(f.seq) : '–';
    const rate = sm && sm.rate_hz !== null ? sm.rate_hz : null;
    $('rate').textContent = rate !== null ? `${fmt(rate, 1)} Hz → ${h ? h.view.display_hz : '–'} Hz` : '–';
    if (s) {
      const stateClass = { RUNNING: 'good', HOMING: 'warn', STARTING: 'warn', DEGRADED: 'warn',
        FAULT: 'bad', STOPPING: 'bad' }[s.state];
      badge($('service'), s.state, stateClass);
      const c = s.clock;
      const clockText = c.synchronised ? (c.est_error_us === null ? 'synced (error unknown)' : `synced ±${fmt(c.est_error_us, 0)} µs`)
        : c.required ? 'NOT SYNCHRONISED' : 'not synchronised (ignored by the config)';
      badge($('clock'), clockText, c.synchronised && c.steps === 0 ? 'good' : c.required ? 'warn' : '');
      $('message').textContent = s.message;
      $('loop').textContent = `lateness p99 ${fmt(s.loop.lateness_p99_us, 1)} µs, max ${fmt(s.loop.lateness_max_us, 1)} µs, ` +
        `overruns ${s.loop.overruns}, cycles ${s.loop.cycles}`;
      $('source').textContent = `${s.source}, bus ${s.bus}, frames ${s.source_stats.frames}, ` +
        `missing ${s.source_stats.missing_samples}, seq gaps ${s.source_stats.seq_gaps}`;
      // The backend's state and the counters that are not zero (source_status_t).
      const b = s.backend;
      $('backend').textContent = b === null ? '–' : [b.state].concat(Object.entries(b.counters)
        .filter(([, v]) => v !== 0).map(([k, v]) => `${k.replace(/_/g, ' ')} ${v}`)).join(', ');
      $('clock-detail').textContent = `${c.synchronised ? 'synchronised' : 'not synchronised'}, est error ${c.est_error_us === null ? 'unknown' : fmt(c.est_error_us, 1) + ' µs'}, ` +
        `max error ${c.max_error_us === null ? 'unknown' : fmt(c.max_error_us, 1) + ' µs'}, offset ${fmt(c.offset_us, 1)} µs, steps ${c.steps}`;
    }
    if (d === 'stopped') badge($('service'), 'STOPPED', 'bad');
    // A status that stopped coming is the last word of a service that may be gone.
    else if (s && (d === 'no-data' || d === 'disconnected')) {
      const age = sm && sm.status_age_s !== null ? ` (${fmt(sm.status_age_s, 0)} s ago)` : '';
      badge($('service'), `${s.state}?${d === 'no-data' ? age : ''}`, '');
    }
    if (sm) {
      $('stream').textContent = `${sm.state}` + (sm.age_s !== null ? `, last joint state ${fmt(sm.age_s, 1)} s ago` : '') +
        (sm.received !== null ? `, received ${fmt(sm.received * 100, 1)} %` : '');
    }
    if (h) {
      $('trail-s').textContent = String(h.view.trail_s);
      $('model').textContent = `model ${h.model.name}${h.model.calibrated ? ' + calibration' : ''}`;
      $('view-info').textContent = `${h.view.url}, prefix '${h.view.prefix}', ${st.framesDrawn} frames drawn`;
    }
    if (f) updateJoints(f);
  }

  function updateJoints(f) {
    const body = document.querySelector('#joints tbody');
    while (body.rows.length < f.q.length) {
      const tr = body.insertRow();
      for (let c = 0; c < 6; c++) tr.insertCell();
      tr.cells[0].innerHTML = '<span class="dot"></span>';
    }
    const limits = st.hello ? st.hello.model.limits : [];
    for (let i = 0; i < f.q.length; i++) {
      const c = body.rows[i].cells;
      c[0].firstChild.className = 'dot ' + f.class[i];
      c[1].textContent = f.names[i] || (st.hello ? st.hello.model.joint_names[i] : '') || `joint ${i + 1}`;
      c[2].textContent = fmt(f.q[i] * RAD2DEG, 2);
      if (limits[i]) c[2].title = `limits ${fmt(limits[i][0] * RAD2DEG, 1)} … ${fmt(limits[i][1] * RAD2DEG, 1)} °`;
      c[3].textContent = fmt(f.qd[i] * RAD2DEG, 1);
      c[4].textContent = f.homed[i] ? 'yes' : 'no';
      c[5].textContent = f.flag_names[i];
    }
    $('palm').textContent = f.palm.map((x) => fmt(x * 1000, 1)).join(', ');
    const p = f.published;
    $('palm-valid').textContent = p ? (p.valid ? 'yes' : 'no (' + p.invalid_names + ')') +
      (f.fk_error_m !== null && f.fk_error_m > 1e-3 ? `; model mismatch: ${fmt(f.fk_error_m * 1000, 1)} mm from the published palm` : '') : '–';
    $('manip').textContent = p ? fmt(p.manipulability, 3) + (p.near_singular ? ' NEAR SINGULAR' : '') : '–';
    $('sample-flags').textContent = f.sample_flag_names;
  }

  // ---- the event stream ---------------------------------------------------
  function trimTrail() {
    if (!st.hello || st.trail.length === 0) return;
    const newest = st.trail[st.trail.length - 1][0];
    while (st.trail.length && st.trail[0][0] < newest - st.hello.view.trail_s) st.trail.shift();
  }

  function onEvent(name, handler) {
    return (e) => {
      st.lastEventMs = performance.now();
      st.counts[name]++;
      if (st.connection !== 'open') st.connection = 'open';
      let data;
      try { data = JSON.parse(e.data); } catch (err) { st.counts.errors++; return; }
      handler(data);
      draw();
      updateText();
    };
  }

  function connect() {
    const es = new EventSource('events');
    es.addEventListener('hello', onEvent('hello', (h) => {
      st.hello = h;
      st.trail = h.trail.slice();
      st.frame = h.frame;
      st.status = h.status;
      st.stream = h.stream;
    }));
    es.addEventListener('frame', onEvent('frame', (f) => {
      if (st.frame && st.frame.run_id !== f.run_id) st.trail = [];  // a new daemon run
      st.frame = f;
      st.trail.push([f.t].concat(f.palm));
      trimTrail();
    }));
    es.addEventListener('status', onEvent('status', (s) => { st.status = s; }));
    es.addEventListener('stream', onEvent('stream', (s) => { st.stream = s; }));
    es.onopen = () => { st.lastEventMs = performance.now(); };
    es.onerror = () => {
      // EventSource reconnects by itself (retry: 1000); show the loss meanwhile.
      st.connection = 'lost';
      draw();
      updateText();
    };
  }

  // A server that stops sending without closing the connection.
  setInterval(() => {
    if (st.connection === 'open' && performance.now() - st.lastEventMs > QUIET_MS) {
      st.connection = 'lost';
      draw();
      updateText();
    }
  }, 250);

  window.exodaqView = {
    // A copy of the page's state: connection, stream, what was last drawn.
    state() {
      return JSON.parse(JSON.stringify({
        connection: st.connection, display: display(), stream: st.stream, status: st.status,
        drawn: st.drawn, frames_drawn: st.framesDrawn, counts: st.counts,
        trail_points: st.trail.length, banner: $('banner').textContent,
        model: st.hello ? st.hello.model : null, view: st.hello ? st.hello.view : null,
        device_pixel_ratio: window.devicePixelRatio || 1,
      }));
    },
    // The canvas pixel [r, g, b, a] at CSS pixel (x, y).
    pixel(x, y) {
      const dpr = window.devicePixelRatio || 1;
      return Array.from(ctx.getImageData(Math.round(x * dpr), Math.round(y * dpr), 1, 1).data);
    },
    colours: COLOURS,
  };

  setupCanvas();
  draw();
  updateText();
  connect();
})();
