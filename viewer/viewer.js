// The player of `mbdae view` (docs/viewer.md): draws the shapes of /geometry at the
// rows of the results file with three.js (the global THREE), plays them, and plots one
// series with a cursor at the current time. DATA is the JSON the program wrote.
// window.mbdae exposes hooks for tests (setTime, camera, bodyPosition, plot, ...);
// window.mbdaeReady turns true after the first frame is drawn.
(function () {
  'use strict';
  const D = DATA;
  const nFrames = D.time.length;
  const L = D.length_scale > 0 ? D.length_scale : 1;

  // ---- layout ----------------------------------------------------------------------------
  const view = document.getElementById('view');
  const bar = document.getElementById('bar');
  const plotbox = document.getElementById('plotbox');
  const banner = document.getElementById('banner');
  document.getElementById('title').textContent = D.title;
  document.getElementById('info').textContent =
      D.file.split('/').pop() + ' | ' + D.rows_total + ' rows' +
      (D.stride > 1 ? ' (' + nFrames + ' drawn: one row in ' + D.stride + ' and the last; at most ' + D.max_frames + ')' : '') +
      ' | status ' + D.status;
  if (D.status !== 'done') {
    const t = D.t_reached;
    banner.style.display = 'block';
    if (D.status === 'failed') {
      banner.textContent = 'This run failed at t = ' + t + ' s' + (D.failure ? ': ' + D.failure : '') +
          '. Shown: its ' + D.rows_total + ' rows up to the failure.';
    } else {
      banner.className = 'note';
      banner.textContent = 'This run is ' + D.status + ' (t reached: ' + t + ' s). Shown: the ' +
          D.rows_total + ' rows the file holds.';
    }
  }
  if (nFrames === 0) {
    banner.style.display = 'block';
    banner.textContent = (banner.textContent ? banner.textContent + ' ' : '') + 'The file has no rows: nothing to play.';
  }

  function layout() {
    const top = document.getElementById('top').offsetHeight + (banner.style.display === 'block' ? banner.offsetHeight : 0);
    const H = window.innerHeight;
    const plotH = Math.max(120, Math.round(0.3 * (H - top)));
    const barH = 34;
    view.style.top = top + 'px';
    view.style.height = (H - top - plotH - barH) + 'px';
    bar.style.top = (H - plotH - barH) + 'px';
    plotbox.style.height = plotH + 'px';
  }
  layout();

  // ---- scene -----------------------------------------------------------------------------
  const canvas = document.getElementById('scene');
  const renderer = new THREE.WebGLRenderer({canvas: canvas, antialias: true, preserveDrawingBuffer: true});
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setClearColor(0xf4f5f7, 1);
  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(40, 1, L * 1e-3, L * 1e3);
  scene.add(new THREE.AmbientLight(0xffffff, 0.55));
  const sun = new THREE.DirectionalLight(0xffffff, 0.6);
  scene.add(sun);

  // "Up" is against gravity (z without gravity).
  const g = new THREE.Vector3(D.gravity[0], D.gravity[1], D.gravity[2]);
  const up = g.lengthSq() > 0 ? g.clone().negate().normalize() : new THREE.Vector3(0, 0, 1);
  camera.up.copy(up);

  function quat(e) { return new THREE.Quaternion(e[1], e[2], e[3], e[0]); }  // e0 scalar first
  function vec(p) { return new THREE.Vector3(p[0], p[1], p[2]); }

  function shapeGeometry(s) {
    const a = s.size;
    let geo;
    switch (s.kind) {
      case 'box': return new THREE.BoxBufferGeometry(a[0], a[1], a[2]);
      case 'sphere': return new THREE.SphereBufferGeometry(a[0], 32, 20);
      case 'ellipsoid': geo = new THREE.SphereBufferGeometry(1, 32, 20); geo.scale(a[0], a[1], a[2]); return geo;
      case 'cylinder': geo = new THREE.CylinderBufferGeometry(a[0], a[0], a[1], 32); geo.rotateX(Math.PI / 2); return geo;
      case 'cone':  // apex towards +z, origin at the centroid (length/4 above the base)
        geo = new THREE.ConeBufferGeometry(a[0], a[1], 32); geo.translate(0, a[1] / 4, 0); geo.rotateX(Math.PI / 2); return geo;
      case 'mesh': {
        const m = D.meshes[s.mesh];
        geo = new THREE.BufferGeometry();
        geo.setAttribute('position', new THREE.Float32BufferAttribute(m.v, 3));
        geo.setIndex(m.f);
        geo.computeVertexNormals();
        return geo;
      }
    }
    return null;
  }

  function shapeObject(s) {
    const material = new THREE.MeshPhongMaterial({
      color: new THREE.Color(s.color[0], s.color[1], s.color[2]), shininess: 40,
      transparent: s.color[3] < 1, opacity: s.color[3], side: s.kind === 'mesh' ? THREE.DoubleSide : THREE.FrontSide});
    let obj;
    if (s.kind === 'capsule') {  // a cylinder and two spheres
      obj = new THREE.Group();
      const r = s.size[0], h = s.size[1];
      const c = new THREE.CylinderBufferGeometry(r, r, h, 32); c.rotateX(Math.PI / 2);
      obj.add(new THREE.Mesh(c, material));
      for (const z of [-h / 2, h / 2]) {
        const b = new THREE.Mesh(new THREE.SphereBufferGeometry(r, 32, 16), material);
        b.position.set(0, 0, z);
        obj.add(b);
      }
    } else {
      obj = new THREE.Mesh(shapeGeometry(s), material);
    }
    obj.position.copy(vec(s.pos));
    obj.quaternion.copy(quat(s.quat));
    return obj;
  }

  // One group per body (its pose set from the rows), ground's shapes in the scene.
  const groups = D.bodies.map(function (b, k) {
    const grp = new THREE.Group();
    grp.name = b.name;
    grp.userData.body = k;
    scene.add(grp);
    return grp;
  });
  const pickable = [];
  for (const s of D.shapes) {
    const obj = shapeObject(s);
    (s.body >= 0 ? groups[s.body] : scene).add(obj);
    obj.traverse(function (o) {
      if (o.isMesh) { o.userData.label = s.body >= 0 ? D.bodies[s.body].name : 'ground'; pickable.push(o); }
    });
  }

  // Joint frames: axes at both markers of every joint (x red, y green, z blue), hidden at first.
  const frameObjects = [];
  for (const j of D.joints) {
    for (const m of [j.i, j.j]) {
      if (m < 0) continue;
      const mk = D.markers[m];
      const axes = new THREE.AxesHelper(L / 8);
      axes.position.copy(vec(mk.pos));
      axes.quaternion.copy(quat(mk.quat));
      axes.visible = false;
      axes.userData.label = 'joint ' + j.name + ' (' + mk.name + ')';
      (mk.body >= 0 ? groups[mk.body] : scene).add(axes);
      frameObjects.push(axes);
    }
  }

  // ---- rows --------------------------------------------------------------------------------
  let frame = 0;
  function pose(k) {
    D.bodies.forEach(function (b, i) {
      groups[i].position.set(b.p[3 * k], b.p[3 * k + 1], b.p[3 * k + 2]);
      groups[i].quaternion.set(b.q[4 * k + 1], b.q[4 * k + 2], b.q[4 * k + 3], b.q[4 * k]);
    });
  }
  // The drawn row nearest to t.
  function frameAt(t) {
    let lo = 0, hi = nFrames - 1;
    if (nFrames === 0) return 0;
    while (hi - lo > 1) {
      const mid = (lo + hi) >> 1;
      if (D.time[mid] <= t) lo = mid; else hi = mid;
    }
    return Math.abs(D.time[hi] - t) < Math.abs(t - D.time[lo]) ? hi : lo;
  }

  // ---- camera: an orbit around a target, written for this page -----------------------------
  const orbit = {target: new THREE.Vector3(), distance: 1, azimuth: 0.35, elevation: 0.25, e1: new THREE.Vector3(), e2: new THREE.Vector3()};
  function fit() {
    // Everything that moves or is drawn: the centres of mass over all rows, the markers at
    // the first row, ground's shapes; a margin of the default shape size.
    const box = new THREE.Box3();
    for (const b of D.bodies)
      for (let k = 0; k < nFrames; ++k) box.expandByPoint(new THREE.Vector3(b.p[3 * k], b.p[3 * k + 1], b.p[3 * k + 2]));
    for (const m of D.markers) {
      if (m.body < 0) { box.expandByPoint(vec(m.pos)); continue; }
      if (nFrames === 0) continue;
      const b = D.bodies[m.body];
      const p = vec(m.pos).applyQuaternion(new THREE.Quaternion(b.q[1], b.q[2], b.q[3], b.q[0]));
      box.expandByPoint(p.add(new THREE.Vector3(b.p[0], b.p[1], b.p[2])));
    }
    for (const s of D.shapes) if (s.body < 0) box.expandByPoint(vec(s.pos));
    if (box.isEmpty()) box.expandByPoint(new THREE.Vector3());
    box.expandByScalar(L / 20);
    const size = new THREE.Vector3(); box.getSize(size);
    box.getCenter(orbit.target);
    // Look along the world axis (not "up") in which the scene is thinnest: a planar
    // mechanism is seen face on, then turned a little for depth.
    const axes = [new THREE.Vector3(1, 0, 0), new THREE.Vector3(0, 1, 0), new THREE.Vector3(0, 0, 1)];
    const extent = [size.x, size.y, size.z];
    let best = -1;
    for (let k = 0; k < 3; ++k) {
      if (Math.abs(axes[k].dot(up)) > 0.99) continue;
      if (best < 0 || extent[k] < extent[best]) best = k;
    }
    orbit.e1.copy(axes[best]).addScaledVector(up, -axes[best].dot(up)).normalize();
    orbit.e2.crossVectors(up, orbit.e1).normalize();
    // The box seen face on: its extent along "up" fits the height, across it the width.
    const across = Math.abs(size.dot(orbit.e2)), high = Math.abs(size.dot(up)), deep = Math.abs(size.dot(orbit.e1));
    const aspect = Math.max(0.2, canvas.clientWidth / Math.max(1, canvas.clientHeight));
    const tanHalf = Math.tan(camera.fov * Math.PI / 360);
    orbit.distance = 1.08 * Math.max(high / 2 / tanHalf, across / 2 / (tanHalf * aspect)) + deep / 2 + L / 20;
    // Turned a little for depth; less for a wide scene, whose far end would shrink.
    orbit.azimuth = across > 4 * Math.max(high, deep) ? 0.15 : 0.35;
    orbit.elevation = 0.25;
    // A faint grid below everything, across "up".
    if (grid) scene.remove(grid);
    const span = 1.5 * Math.max(across, deep, L);
    grid = new THREE.GridHelper(span, 10, 0xd2d5da, 0xe3e5e8);
    grid.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), up);
    grid.position.copy(orbit.target).addScaledVector(up, -high / 2);
    scene.add(grid);
  }
  let grid = null;
  function placeCamera() {
    const c = Math.cos(orbit.elevation);
    const dir = orbit.e1.clone().multiplyScalar(c * Math.cos(orbit.azimuth))
        .addScaledVector(orbit.e2, c * Math.sin(orbit.azimuth)).addScaledVector(up, Math.sin(orbit.elevation));
    camera.position.copy(orbit.target).addScaledVector(dir, orbit.distance);
    camera.near = orbit.distance * 1e-3;
    camera.far = orbit.distance * 1e2;
    camera.lookAt(orbit.target);
    camera.updateProjectionMatrix();
    sun.position.copy(camera.position).addScaledVector(up, orbit.distance);
  }

  let drag = null;
  canvas.addEventListener('contextmenu', function (e) { e.preventDefault(); });
  canvas.addEventListener('pointerdown', function (e) {
    drag = {x: e.clientX, y: e.clientY, pan: e.button === 2 || e.shiftKey};
    canvas.setPointerCapture(e.pointerId);
  });
  canvas.addEventListener('pointerup', function () { drag = null; });
  canvas.addEventListener('pointermove', function (e) {
    if (drag) {
      const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
      drag.x = e.clientX; drag.y = e.clientY;
      if (drag.pan) {  // move the target in the screen plane
        const s = 2 * orbit.distance * Math.tan(camera.fov * Math.PI / 360) / Math.max(1, canvas.clientHeight);
        const right = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 0);
        const upv = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 1);
        orbit.target.addScaledVector(right, -dx * s).addScaledVector(upv, dy * s);
      } else {
        orbit.azimuth -= dx * 0.008;
        orbit.elevation = Math.max(-1.55, Math.min(1.55, orbit.elevation + dy * 0.008));
      }
      placeCamera();
      requestDraw();
      return;
    }
    hover(e);
  });
  canvas.addEventListener('wheel', function (e) {
    e.preventDefault();
    orbit.distance *= Math.pow(1.1, e.deltaY > 0 ? 1 : -1);
    placeCamera();
    requestDraw();
  }, {passive: false});

  // Names on hover.
  const tip = document.getElementById('tip');
  const raycaster = new THREE.Raycaster();
  function hover(e) {
    const r = canvas.getBoundingClientRect();
    const ndc = new THREE.Vector2((e.clientX - r.left) / r.width * 2 - 1, -(e.clientY - r.top) / r.height * 2 + 1);
    raycaster.setFromCamera(ndc, camera);
    const hit = raycaster.intersectObjects(pickable, false).find(function (h) { return h.object.visible; });
    if (hit) {
      tip.style.display = 'block';
      tip.textContent = hit.object.userData.label;
      tip.style.left = (e.clientX - r.left + 12) + 'px';
      tip.style.top = (e.clientY - r.top + 12) + 'px';
    } else {
      tip.style.display = 'none';
    }
  }

  // ---- plot ----------------------------------------------------------------------------------
  const plotCanvas = document.getElementById('plot');
  const plotSel = document.getElementById('plotsel');
  D.series.forEach(function (s, k) {
    const o = document.createElement('option');
    o.value = k;
    o.textContent = s.name + (s.unit ? ' [' + s.unit + ']' : '');
    plotSel.appendChild(o);
  });
  let plotIndex = 0;
  const plotState = {};
  // Round tick values in [lo, hi]: multiples of 1, 2 or 5 times a power of ten, at most `most`.
  function tickStep(lo, hi, most) {
    const raw = (hi - lo) / most, p = Math.pow(10, Math.floor(Math.log10(raw)));
    return [1, 2, 5, 10].map(function (m) { return m * p; }).find(function (st) { return st >= raw; });
  }
  function ticks(lo, hi, most) {
    if (!(hi > lo)) return [lo];
    const st = tickStep(lo, hi, most), out = [];
    for (let k = Math.ceil(lo / st); k * st <= hi + 1e-9 * st; ++k) out.push(k * st);
    return out;
  }
  function tickLabel(v, lo, hi, most) {
    const st = tickStep(lo, hi, most);
    if (Math.abs(v) < 1e-9 * st) return '0';
    const big = Math.max(Math.abs(lo), Math.abs(hi));
    if (big >= 1e5 || big < 1e-3) return v.toExponential(Math.max(1, Math.ceil(Math.log10(big / st))));
    return v.toFixed(Math.max(0, -Math.floor(Math.log10(st))));
  }
  // A number with the digits that tell the ticks of [lo, hi] apart.
  let tickDigits = 4, tickRange = 0;
  function niceNumber(x) {
    if (x === 0 || Math.abs(x) < 1e-9 * tickRange) return '0';
    if (Math.abs(x) >= 1e5 || Math.abs(x) < 1e-3) return x.toExponential(Math.max(2, tickDigits - 1));
    return String(+x.toPrecision(tickDigits));
  }
  function drawPlot() {
    const dpr = window.devicePixelRatio || 1;
    const W = plotCanvas.clientWidth, H = plotCanvas.clientHeight;
    if (plotCanvas.width !== Math.round(W * dpr) || plotCanvas.height !== Math.round(H * dpr)) {
      plotCanvas.width = Math.round(W * dpr);
      plotCanvas.height = Math.round(H * dpr);
    }
    const c = plotCanvas.getContext('2d');
    c.setTransform(dpr, 0, 0, dpr, 0, 0);
    c.fillStyle = '#ffffff';
    c.fillRect(0, 0, W, H);
    const s = D.series[plotIndex];
    const area = {left: 70, right: W - 20, top: 34, bottom: H - 28};
    if (!s || nFrames === 0 || area.right <= area.left || area.bottom <= area.top) return;
    let y0 = Infinity, y1 = -Infinity;
    for (const v of s.v) if (Number.isFinite(v)) { y0 = Math.min(y0, v); y1 = Math.max(y1, v); }
    if (!isFinite(y0)) { y0 = -1; y1 = 1; }
    if (y1 - y0 < 1e-12 * Math.max(1, Math.abs(y0))) { y0 -= 0.5 * Math.max(1e-12, Math.abs(y0)) || 0.5; y1 = y0 + (y0 === 0 ? 1 : Math.abs(y0)); }
    const pad = 0.05 * (y1 - y0);
    y0 -= pad; y1 += pad;
    tickRange = y1 - y0;
    tickDigits = Math.max(3, Math.min(12, Math.ceil(Math.log10(Math.max(Math.abs(y0), Math.abs(y1)) / (y1 - y0))) + 3));
    const x0 = D.time[0], x1 = nFrames > 1 ? D.time[nFrames - 1] : D.time[0] + 1;
    const X = function (t) { return area.left + (t - x0) / (x1 - x0) * (area.right - area.left); };
    const Y = function (v) { return area.bottom - (v - y0) / (y1 - y0) * (area.bottom - area.top); };
    // axes, ticks
    c.strokeStyle = '#999'; c.lineWidth = 1;
    c.strokeRect(area.left, area.top, area.right - area.left, area.bottom - area.top);
    c.fillStyle = '#333'; c.font = '11px sans-serif';
    c.textAlign = 'right'; c.textBaseline = 'middle';
    for (const v of ticks(y0, y1, 5)) c.fillText(tickLabel(v, y0, y1, 5), area.left - 4, Y(v));
    c.textAlign = 'center'; c.textBaseline = 'top';
    tickDigits = 4;
    tickRange = x1 - x0;
    for (const t of ticks(x0, x1, 6)) c.fillText(tickLabel(t, x0, x1, 6), X(t), area.bottom + 4);
    c.textAlign = 'left'; c.textBaseline = 'top'; c.font = '12px sans-serif';
    c.fillText(s.name + (s.unit ? ' [' + s.unit + ']' : '') + ' against t [s]', area.left, 8);
    // the curve
    c.strokeStyle = '#1f77b4'; c.lineWidth = 2; c.beginPath();
    let pen = false;
    for (let k = 0; k < nFrames; ++k) {
      const v = s.v[k];
      if (!Number.isFinite(v)) { pen = false; continue; }
      if (pen) c.lineTo(X(D.time[k]), Y(v)); else c.moveTo(X(D.time[k]), Y(v));
      pen = true;
    }
    c.stroke();
    // the cursor at the current time
    const xc = X(D.time[frame]);
    c.strokeStyle = '#d62728'; c.lineWidth = 1.5; c.beginPath();
    c.moveTo(xc, area.top); c.lineTo(xc, area.bottom); c.stroke();
    c.fillStyle = '#d62728'; c.textAlign = 'left'; c.textBaseline = 'top';
    tickDigits = Math.max(tickDigits, 6);
    tickRange = 0;
    c.fillText(niceNumber(s.v[frame]), Math.min(xc + 4, area.right - 80), area.top + 2);
    const r = plotCanvas.getBoundingClientRect();
    Object.assign(plotState, {name: s.name, x0: x0, x1: x1, y0: y0, y1: y1,
      left: r.left + area.left, right: r.left + area.right, top: r.top + area.top, bottom: r.top + area.bottom,
      cursor: r.left + xc});
  }
  plotSel.addEventListener('change', function () { plotIndex = +plotSel.value; drawPlot(); });

  // ---- playing -------------------------------------------------------------------------------
  const slider = document.getElementById('slider');
  const clock = document.getElementById('clock');
  const playButton = document.getElementById('play');
  const speedSel = document.getElementById('speed');
  slider.max = Math.max(0, nFrames - 1);
  let playing = false, playTime = nFrames ? D.time[0] : 0, lastWall = 0, pending = false;

  function show(k) {
    frame = Math.max(0, Math.min(nFrames - 1, k));
    if (nFrames) {
      pose(frame);
      slider.value = frame;
      clock.textContent = 't = ' + D.time[frame].toFixed(4) + ' s';
    }
    requestDraw();
  }
  function draw() {
    pending = false;
    const w = canvas.clientWidth, h = canvas.clientHeight;
    if (canvas.width !== Math.round(w * renderer.getPixelRatio()) || canvas.height !== Math.round(h * renderer.getPixelRatio())) {
      renderer.setSize(w, h, false);
      camera.aspect = w / Math.max(1, h);
      camera.updateProjectionMatrix();
    }
    renderer.render(scene, camera);
    drawPlot();
  }
  function requestDraw() {
    if (!pending) { pending = true; requestAnimationFrame(draw); }
  }
  function tick(wall) {
    if (playing && nFrames > 1) {
      if (lastWall) playTime += (wall - lastWall) / 1000 * +speedSel.value;
      lastWall = wall;
      if (playTime > D.time[nFrames - 1]) playTime = D.time[0];
      show(frameAt(playTime));
    }
    requestAnimationFrame(tick);
  }
  function setPlaying(p) {
    playing = p && nFrames > 1;
    lastWall = 0;
    if (playing) playTime = D.time[frame] >= D.time[nFrames - 1] ? D.time[0] : D.time[frame];
    playButton.textContent = playing ? 'Pause' : 'Play';
  }
  playButton.addEventListener('click', function () { setPlaying(!playing); });
  slider.addEventListener('input', function () { setPlaying(false); show(+slider.value); });
  document.getElementById('frames').addEventListener('change', function (e) {
    for (const f of frameObjects) f.visible = e.target.checked;
    requestDraw();
  });
  document.getElementById('fit').addEventListener('click', function () { fit(); placeCamera(); requestDraw(); });
  window.addEventListener('resize', function () { layout(); requestDraw(); });
  window.addEventListener('keydown', function (e) {
    if (e.key === ' ') { setPlaying(!playing); e.preventDefault(); }
    if (e.key === 'ArrowRight') { setPlaying(false); show(frame + 1); }
    if (e.key === 'ArrowLeft') { setPlaying(false); show(frame - 1); }
  });

  // ---- hooks for tests and scripts -----------------------------------------------------------
  window.mbdae = {
    frames: nFrames,
    time: function () { return nFrames ? D.time[frame] : NaN; },
    // Shows the drawn row nearest to t (paused) and draws it; returns that row's time.
    setTime: function (t) { setPlaying(false); show(frameAt(t)); draw(); return D.time[frame]; },
    play: function () { setPlaying(true); },
    pause: function () { setPlaying(false); },
    // The centre of mass of a body as drawn now (world coordinates).
    bodyPosition: function (name) {
      const grp = groups.find(function (x) { return x.name === name; });
      return grp ? [grp.position.x, grp.position.y, grp.position.z] : null;
    },
    camera: function () {
      const r = canvas.getBoundingClientRect();
      return {position: camera.position.toArray(), target: orbit.target.toArray(), up: camera.up.toArray(),
              fov: camera.fov, aspect: camera.aspect, left: r.left, top: r.top, width: r.width, height: r.height};
    },
    plotNames: function () { return D.series.map(function (s) { return s.name; }); },
    selectPlot: function (name) {
      const k = D.series.findIndex(function (s) { return s.name === name; });
      if (k >= 0) { plotIndex = k; plotSel.value = k; drawPlot(); }
      return k >= 0;
    },
    plot: function () { return Object.assign({}, plotState); },
    setJointFrames: function (on) {
      document.getElementById('frames').checked = on;
      for (const f of frameObjects) f.visible = on;
      draw();
    },
    status: function () { return {status: D.status, rows: D.rows_total, drawn: nFrames, banner: banner.textContent}; }
  };

  fit();
  placeCamera();
  show(0);
  draw();
  window.mbdaeReady = true;
  requestAnimationFrame(tick);
})();
