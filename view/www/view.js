// Felt's live view (docs/view.md). A classic script for three.js r111 (Debian's libjs-three:
// the global THREE, OrbitControls from examples/js), no modules, nothing fetched but this
// server's own files. Receives the static scene as JSON on connect, then binary frames:
// header (48 bytes), float32 positions [3 n], device blocks [36 floats each], stats [8 floats].
'use strict';

(function () {
  const kMagic = 0x564C4546;  // "FELV"
  const kClothColour = new THREE.Color(0x6fa8dc);
  const kStretchColour = new THREE.Color(0xe04030);
  const kProxyColour = 0xffaa00;    // unlit: the tests look for exactly this colour
  const kDeviceColour = 0xff00ff;
  const kPatchColour = 0x30e040;
  const kForceMetresPerNewton = 0.1;  // force arrow length per newton

  const container = document.getElementById('scene');
  const statusEl = document.getElementById('status');
  const stretchBox = document.getElementById('stretch');
  if (/[?&]stretch=1/.test(location.search)) stretchBox.checked = true;  // ?stretch=1
  const renderer = new THREE.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setSize(window.innerWidth, window.innerHeight);
  renderer.setClearColor(0x20242a);
  container.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(40, window.innerWidth / window.innerHeight, 0.01, 50);
  const controls = new THREE.OrbitControls(camera, renderer.domElement);
  scene.add(new THREE.AmbientLight(0xffffff, 0.35));
  const light = new THREE.DirectionalLight(0xffffff, 0.75);
  camera.add(light);  // a head light: the side facing the viewer is lit
  scene.add(camera);

  const view = {frames: 0, bytes: 0, staticScene: null, lastFrame: -1};
  window.feltView = view;
  let cloth = null;      // {mesh, geometry, positions, colours, width, height, spacing}
  let devices = [];      // per device: {point, proxy, spring, arrow, patch}
  let fitted = false;

  const charts = [
    {el: document.getElementById('chart-force'), label: '|F| N', data: []},
    {el: document.getElementById('chart-late'), label: 'haptic lateness p99 us', data: []},
    {el: document.getElementById('chart-frame'), label: 'sim frame p50 ms', data: []},
  ];

  function v3(a) { return new THREE.Vector3(a[0], a[1], a[2]); }

  function buildObstacles(list) {
    const material = new THREE.MeshLambertMaterial({color: 0x808890, side: THREE.DoubleSide});
    for (const o of list) {
      let mesh = null;
      if (o.type === 'sphere') {
        mesh = new THREE.Mesh(new THREE.SphereBufferGeometry(o.radius, 32, 16), material);
        mesh.position.copy(v3(o.center));
      } else if (o.type === 'box') {
        const lo = v3(o.min), hi = v3(o.max);
        const size = hi.clone().sub(lo);
        mesh = new THREE.Mesh(new THREE.BoxBufferGeometry(size.x, size.y, size.z), material);
        mesh.position.copy(lo.add(hi).multiplyScalar(0.5));
      } else if (o.type === 'plane') {
        mesh = new THREE.Mesh(new THREE.PlaneBufferGeometry(2, 2), material);
        mesh.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), v3(o.normal).normalize());
        mesh.position.copy(v3(o.point));
      } else if (o.type === 'capsule') {
        const a = v3(o.a), b = v3(o.b);
        const axis = b.clone().sub(a);
        const group = new THREE.Group();
        const body = new THREE.Mesh(
            new THREE.CylinderBufferGeometry(o.radius, o.radius, axis.length(), 24), material);
        body.position.copy(a.clone().add(b).multiplyScalar(0.5));
        body.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), axis.clone().normalize());
        group.add(body);
        for (const end of [a, b]) {
          const cap = new THREE.Mesh(new THREE.SphereBufferGeometry(o.radius, 24, 12), material);
          cap.position.copy(end);
          group.add(cap);
        }
        mesh = group;
      }
      if (mesh) scene.add(mesh);
    }
  }

  function buildScene(s) {
    view.staticScene = s;
    const n = s.width * s.height;
    const geometry = new THREE.BufferGeometry();
    const positions = new Float32Array(3 * n);
    const colours = new Float32Array(3 * n);
    geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
    geometry.setAttribute('color', new THREE.BufferAttribute(colours, 3));
    geometry.setIndex(s.triangles);
    const material = new THREE.MeshLambertMaterial(
        {vertexColors: THREE.VertexColors, side: THREE.DoubleSide});
    const mesh = new THREE.Mesh(geometry, material);
    mesh.frustumCulled = false;
    scene.add(mesh);
    cloth = {mesh, geometry, positions, colours, width: s.width, height: s.height,
             spacing: s.spacing_m, triangles: s.triangles};
    buildObstacles(s.obstacles);
    for (const d of s.devices) {
      const point = new THREE.Mesh(new THREE.SphereBufferGeometry(Math.max(0.3 * d.radius_m, 0.002),
                                                                  12, 8),
                                   new THREE.MeshBasicMaterial({color: kDeviceColour}));
      const proxy = new THREE.Mesh(new THREE.SphereBufferGeometry(d.radius_m, 24, 16),
                                   new THREE.MeshBasicMaterial({color: kProxyColour}));
      const springGeometry = new THREE.BufferGeometry();
      springGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(6), 3));
      const spring = new THREE.Line(springGeometry, new THREE.LineBasicMaterial({color: kDeviceColour}));
      spring.frustumCulled = false;
      const arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 0.1,
                                          0xff3030);
      const patchGeometry = new THREE.BufferGeometry();
      patchGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(27), 3));
      patchGeometry.setDrawRange(0, 0);
      const patch = new THREE.Mesh(patchGeometry, new THREE.MeshBasicMaterial(
          {color: kPatchColour, side: THREE.DoubleSide, polygonOffset: true,
           polygonOffsetFactor: -2, polygonOffsetUnits: -2}));
      patch.frustumCulled = false;
      for (const o of [point, proxy, spring, arrow, patch]) scene.add(o);
      devices.push({point, proxy, spring, arrow, patch});
    }
  }

  // Per-vertex stretch: the longest grid edge at the vertex over its rest length (the spacing).
  function colourCloth(stretch) {
    const {positions, colours, width, height, spacing} = cloth;
    const c = new THREE.Color();
    for (let r = 0; r < height; ++r) {
      for (let q = 0; q < width; ++q) {
        const i = r * width + q;
        let ratio = 1;
        if (stretch) {
          for (const [dq, dr] of [[1, 0], [-1, 0], [0, 1], [0, -1]]) {
            const qq = q + dq, rr = r + dr;
            if (qq < 0 || rr < 0 || qq >= width || rr >= height) continue;
            const j = rr * width + qq;
            const dx = positions[3 * i] - positions[3 * j];
            const dy = positions[3 * i + 1] - positions[3 * j + 1];
            const dz = positions[3 * i + 2] - positions[3 * j + 2];
            ratio = Math.max(ratio, Math.sqrt(dx * dx + dy * dy + dz * dz) / spacing);
          }
        }
        c.copy(kClothColour).lerp(kStretchColour, Math.min(1, Math.max(0, (ratio - 1) / 0.1)));
        colours[3 * i] = c.r; colours[3 * i + 1] = c.g; colours[3 * i + 2] = c.b;
      }
    }
    cloth.geometry.attributes.color.needsUpdate = true;
  }

  function fitCamera() {
    cloth.geometry.computeBoundingBox();
    const box = cloth.geometry.boundingBox;
    const centre = box.getCenter(new THREE.Vector3());
    const size = box.getSize(new THREE.Vector3());
    const extent = Math.max(size.x, size.y, size.z, 0.05);
    const distance = 0.75 * extent / Math.tan(camera.fov * Math.PI / 360);
    camera.position.set(centre.x, centre.y, centre.z + distance);  // the user stands on +z
    controls.target.copy(centre);
    controls.update();
  }

  function onFrame(buffer) {
    const dv = new DataView(buffer);
    if (dv.getUint32(0, true) !== kMagic || !cloth) return;
    const headerBytes = dv.getUint16(6, true);
    const n = dv.getUint32(8, true);
    const deviceCount = dv.getUint32(12, true);
    const deviceFloats = dv.getUint32(16, true);
    const statsFloats = dv.getUint32(20, true);
    const frame = dv.getFloat64(32, true);
    const xyz = new Float32Array(buffer, headerBytes, 3 * n);
    const dev = new Float32Array(buffer, headerBytes + 12 * n, deviceCount * deviceFloats);
    const stats = new Float32Array(buffer, headerBytes + 12 * n + 4 * deviceCount * deviceFloats,
                                   statsFloats);
    cloth.positions.set(xyz);
    cloth.geometry.attributes.position.needsUpdate = true;
    cloth.geometry.computeVertexNormals();  // shaded with its normals
    colourCloth(stretchBox.checked);
    if (!fitted) { fitCamera(); fitted = true; }
    let maxForce = 0;
    for (let i = 0; i < deviceCount && i < devices.length; ++i) {
      const b = dev.subarray(i * deviceFloats, (i + 1) * deviceFloats);
      const d = devices[i];
      d.point.position.set(b[0], b[1], b[2]);
      d.proxy.position.set(b[3], b[4], b[5]);
      const springPos = d.spring.geometry.attributes.position;
      springPos.array.set([b[0], b[1], b[2], b[3], b[4], b[5]]);
      springPos.needsUpdate = true;
      const force = new THREE.Vector3(b[6], b[7], b[8]);
      const magnitude = b[9];
      maxForce = Math.max(maxForce, magnitude);
      d.arrow.visible = magnitude > 1e-4;
      if (d.arrow.visible) {
        d.arrow.position.copy(d.proxy.position);
        d.arrow.setDirection(force.normalize());
        d.arrow.setLength(Math.max(magnitude * kForceMetresPerNewton, 0.005));
      }
      // The contact patch: the triangles the proxy touches.
      const contacts = Math.min(3, b[10] | 0);
      const patchPos = d.patch.geometry.attributes.position;
      let used = 0;
      for (let k = 0; k < contacts; ++k) {
        const t = b[12 + 8 * k + 6] | 0;
        if (t < 0) continue;  // a static obstacle's contact
        for (let v = 0; v < 3; ++v) {
          const p = cloth.triangles[3 * t + v];
          patchPos.array[3 * used] = xyz[3 * p];
          patchPos.array[3 * used + 1] = xyz[3 * p + 1];
          patchPos.array[3 * used + 2] = xyz[3 * p + 2];
          ++used;
        }
      }
      d.patch.geometry.setDrawRange(0, used);
      patchPos.needsUpdate = true;
    }
    charts[0].data.push(maxForce);
    charts[1].data.push(stats[0]);
    charts[2].data.push(stats[2]);
    for (const c of charts) if (c.data.length > c.el.width) c.data.shift();
    view.frames += 1;
    view.lastFrame = frame;
    view.stats = Array.from(stats);
  }

  function drawChart(c) {
    const g = c.el.getContext('2d');
    const w = c.el.width, h = c.el.height;
    g.fillStyle = 'rgba(0,0,0,0.5)';
    g.fillRect(0, 0, w, h);
    const top = Math.max(1e-6, ...c.data) * 1.1;
    g.strokeStyle = '#9fd';
    g.beginPath();
    c.data.forEach((v, i) => {
      const y = h - (v / top) * (h - 12);
      if (i === 0) g.moveTo(i, y); else g.lineTo(i, y);
    });
    g.stroke();
    g.fillStyle = '#dde';
    const last = c.data.length ? c.data[c.data.length - 1] : 0;
    g.fillText(c.label + ': ' + last.toFixed(3) + ' (max ' + (top / 1.1).toFixed(3) + ')', 4, 10);
  }

  let lastStatus = performance.now(), framesAtStatus = 0, bytesAtStatus = 0;
  function animate() {
    requestAnimationFrame(animate);
    const now = performance.now();
    if (now - lastStatus > 500) {
      const dt = (now - lastStatus) / 1000;
      const fps = (view.frames - framesAtStatus) / dt;
      const kbps = (view.bytes - bytesAtStatus) / dt / 1024;
      statusEl.textContent = (view.staticScene ? view.staticScene.scene : '') + '  frame ' +
          view.lastFrame + '  ' + fps.toFixed(0) + ' frames/s  ' + kbps.toFixed(0) + ' KiB/s';
      lastStatus = now; framesAtStatus = view.frames; bytesAtStatus = view.bytes;
      for (const c of charts) drawChart(c);
    }
    renderer.render(scene, camera);
  }

  window.addEventListener('resize', () => {
    camera.aspect = window.innerWidth / window.innerHeight;
    camera.updateProjectionMatrix();
    renderer.setSize(window.innerWidth, window.innerHeight);
  });

  function connect() {
    const ws = new WebSocket('ws://' + location.host + '/ws');
    ws.binaryType = 'arraybuffer';
    ws.onmessage = (e) => {
      if (typeof e.data === 'string') {
        view.bytes += e.data.length;
        if (!cloth) buildScene(JSON.parse(e.data));
      } else {
        view.bytes += e.data.byteLength;
        onFrame(e.data);
      }
    };
    ws.onclose = () => { statusEl.textContent = 'disconnected; retrying...'; setTimeout(connect, 1000); };
  }
  connect();
  animate();
})();
