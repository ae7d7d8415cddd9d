// The WebGL walkthrough of an exported fit (scene.glb, format "vlights.fit.gltf" v1;
// display/export.py and the README's "Export" hold the schema).
//
// Shading is Contract 2's formula per pixel, as `vlights render --shading pixel` draws it,
// with the renderer's own GLSL (display/renderer.py SHADE_GLSL, written into shading.js
// by `vlights export`): emitted colour plus, for each virtual light k,
//     pow(dot(n, h), shininess_k) * rgb_k * coefficient_k
// with h the half vector of the light direction normalize(xyz - w x) and the eye
// direction, and the lobe cut to 0 where (1 - dot(n, h)) * shininess > 30. Coefficients
// are shared by the lights (the vertex attribute _SPECULAR) or one per light
// (_SPECULAR_k): those are blended from the triangle's three vertices by barycentrics, as
// the renderer's geometry-shader program does. The scene is drawn in linear radiance into
// a float framebuffer (MSAA, `samples` per pixel), then exposure, clipping and sRGB map it
// to the screen exactly as display.renderer.tonemap.
//
// URL query (all optional): eye=x,y,z look=x,y,z up=x,y,z fov=deg mode=fitted|diffuse
// exposure=e lights=n samples=1|2|4 file=scene.glb. document.title becomes "rendered"
// after the first complete frame ("error" if the scene cannot be shown).
//
// Keys: W A S D walk, Q E down / up, Shift faster, mouse look after a click (Esc frees
// the mouse); M fitted / diffuse-only; L two lights / all lights; + - exposure x2 / x0.5;
// O orbit / walk; R back to the start camera; H hides this help.

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { PointerLockControls } from 'three/addons/controls/PointerLockControls.js';
// written by `vlights export` from display/renderer.py: the renderer's own shading code
import { SHADE_GLSL, TEXTURE_WIDTH } from './shading.js';

const FORMAT = 'vlights.fit.gltf';
const VERSION = 1;
const MODES = ['fitted', 'diffuse'];
const DEFAULT_FOV = 39.3; // display.camera.framing_view


const FITTED_VS = `
precision highp float;
precision highp int;
uniform mat4 modelViewMatrix;
uniform mat4 projectionMatrix;
in vec3 position;
in vec3 normal;
in vec3 emitted;
in vec3 specular;
in vec3 vertices;   // per light: the triangle's three vertex ids (else 0)
in vec3 bary;       // per light: this corner's barycentrics (else 0)
centroid out vec3 v_position;
centroid out vec3 v_normal;
centroid out vec3 v_emitted;
centroid out vec3 v_specular;
centroid out vec3 v_bary;
flat out ivec3 v_vertices;
void main() {
    gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
    v_position = position;
    v_normal = normal;
    v_emitted = emitted;
    v_specular = specular;
    v_bary = bary;
    v_vertices = ivec3(vertices);
}
`;

const FITTED_FS = `
precision highp float;
precision highp int;
precision highp sampler2D;
uniform vec3 eye;
centroid in vec3 v_position;
centroid in vec3 v_normal;
centroid in vec3 v_emitted;
centroid in vec3 v_specular;
centroid in vec3 v_bary;
flat in ivec3 v_vertices;
out vec4 f_colour;
${SHADE_GLSL}
void main() {
    f_colour = vec4(shade(normalize(v_normal), v_position, normalize(eye - v_position), v_emitted, v_specular,
                          v_vertices, v_bary), 1.0);
}
`;

const TONEMAP_VS = `
precision highp float;
in vec3 position;
void main() { gl_Position = vec4(position.xy, 0.0, 1.0); }
`;

// display.renderer.tonemap: exposure, clip to [0, 1], sRGB; the 8-bit write rounds
const TONEMAP_FS = `
precision highp float;
uniform highp sampler2D hdr;
uniform float exposure;
out vec4 f_colour;
void main() {
    vec3 x = clamp(texelFetch(hdr, ivec2(gl_FragCoord.xy), 0).rgb * exposure, 0.0, 1.0);
    vec3 srgb = mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, x));
    f_colour = vec4(clamp(srgb, 0.0, 1.0), 1.0);
}
`;

// ---------------------------------------------------------------------------------- query

export function parseQuery(search) {
    const q = new URLSearchParams(search);
    const state = {};
    const vec = (key) => {
        if (!q.has(key)) return undefined;
        const v = q.get(key).split(',').map(Number);
        if (v.length !== 3 || !v.every(Number.isFinite)) throw new Error(`${key}: want three numbers x,y,z, got '${q.get(key)}'`);
        return v;
    };
    const num = (key, ok, what) => {
        if (!q.has(key)) return undefined;
        const v = Number(q.get(key));
        if (!Number.isFinite(v) || !ok(v)) throw new Error(`${key}: want ${what}, got '${q.get(key)}'`);
        return v;
    };
    state.eye = vec('eye');
    state.look = vec('look');
    state.up = vec('up');
    state.fov = num('fov', (v) => v > 0 && v < 180, 'degrees in (0, 180)');
    state.exposure = num('exposure', (v) => v > 0, 'a positive number');
    state.lights = num('lights', (v) => Number.isInteger(v) && v >= 0, 'a whole number >= 0');
    state.samples = num('samples', (v) => [1, 2, 4].includes(v), '1, 2 or 4');
    if (q.has('mode')) {
        if (!MODES.includes(q.get('mode'))) throw new Error(`mode: want ${MODES.join(' or ')}, got '${q.get('mode')}'`);
        state.mode = q.get('mode');
    }
    state.file = q.get('file') || 'scene.glb';
    return state;
}

// --------------------------------------------------------------------------------- objects

function floatTexture(data, width, height) {
    const texture = new THREE.DataTexture(data, width, height, THREE.RGBAFormat, THREE.FloatType);
    texture.minFilter = THREE.NearestFilter;
    texture.magFilter = THREE.NearestFilter;
    texture.generateMipmaps = false;
    texture.needsUpdate = true;
    return texture;
}

function lightTexture(info) {
    const k = info.lights;
    const data = new Float32Array(2 * Math.max(k, 1) * 4);
    for (let i = 0; i < k; ++i) {
        data.set(info.light_pos[i], 8 * i);
        data.set([...info.light_rgb[i], info.shininess[i]], 8 * i + 4);
    }
    return floatTexture(data, 2, Math.max(k, 1));
}

// per-light coefficients of every vertex, texel v * K + k (the renderer's layout)
function coefficientTexture(attributes, v, k) {
    const n = Math.max(v * k, 1);
    const height = Math.ceil(n / TEXTURE_WIDTH);
    const data = new Float32Array(TEXTURE_WIDTH * height * 4);
    for (let light = 0; light < k; ++light) {
        const a = attributes[`_specular_${light}`].array;
        for (let i = 0; i < v; ++i) {
            const t = 4 * (i * k + light);
            data[t] = a[3 * i];
            data[t + 1] = a[3 * i + 1];
            data[t + 2] = a[3 * i + 2];
        }
    }
    return floatTexture(data, TEXTURE_WIDTH, height);
}

function requireAttribute(geometry, name, where) {
    const a = geometry.attributes[name];
    if (!a || a.itemSize !== 3) throw new Error(`${where}: vertex attribute ${name.toUpperCase()} (VEC3) is missing`);
    return a;
}

// The triangle geometry of one object for the shader: indexed with shared coefficients;
// with per-light ones, one vertex per triangle corner carrying the triangle's vertex ids
// and the corner's barycentrics (what the renderer's geometry shader hands its fragments).
function objectGeometry(source, info) {
    const where = `object '${info.name}'`;
    const position = requireAttribute(source, 'position', where);
    const normal = requireAttribute(source, 'normal', where);
    const emitted = requireAttribute(source, '_emitted', where);
    const v = position.count;
    const k = info.lights;
    if (!source.index) throw new Error(`${where}: the mesh has no indices`);
    const faces = source.index.array;
    if (!info.per_light) {
        const g = new THREE.BufferGeometry();
        g.setIndex(new THREE.BufferAttribute(faces, 1));
        g.setAttribute('position', position);
        g.setAttribute('normal', normal);
        g.setAttribute('emitted', emitted);
        const specular = k > 0 ? requireAttribute(source, '_specular', where) : new THREE.BufferAttribute(new Float32Array(3 * v), 3);
        g.setAttribute('specular', specular);
        g.setAttribute('vertices', new THREE.BufferAttribute(new Float32Array(3 * v), 3));
        g.setAttribute('bary', new THREE.BufferAttribute(new Float32Array(3 * v), 3));
        return { geometry: g, coefficients: null };
    }
    for (let i = 0; i < k; ++i) requireAttribute(source, `_specular_${i}`, where);
    const corners = faces.length;
    const out = {
        position: new Float32Array(3 * corners), normal: new Float32Array(3 * corners),
        emitted: new Float32Array(3 * corners), vertices: new Float32Array(3 * corners),
        bary: new Float32Array(3 * corners),
    };
    const src = { position: position.array, normal: normal.array, emitted: emitted.array };
    for (let c = 0; c < corners; ++c) {
        const vertex = faces[c];
        const tri = c - (c % 3);
        for (const key of ['position', 'normal', 'emitted']) {
            out[key][3 * c] = src[key][3 * vertex];
            out[key][3 * c + 1] = src[key][3 * vertex + 1];
            out[key][3 * c + 2] = src[key][3 * vertex + 2];
        }
        out.vertices.set([faces[tri], faces[tri + 1], faces[tri + 2]], 3 * c);
        out.bary[3 * c + (c % 3)] = 1;
    }
    const g = new THREE.BufferGeometry();
    for (const [key, array] of Object.entries(out)) g.setAttribute(key, new THREE.BufferAttribute(array, 3));
    g.setAttribute('specular', new THREE.BufferAttribute(new Float32Array(3 * corners), 3));
    return { geometry: g, coefficients: coefficientTexture(source.attributes, v, k) };
}

const EMPTY = floatTexture(new Float32Array(4), 1, 1);

function makeObject(source, info) {
    const { geometry, coefficients } = objectGeometry(source, info);
    const material = new THREE.RawShaderMaterial({
        glslVersion: THREE.GLSL3,
        vertexShader: FITTED_VS,
        fragmentShader: FITTED_FS,
        side: THREE.DoubleSide, // one-sided surfaces are still seen from behind
        uniforms: {
            eye: { value: new THREE.Vector3() },
            n_lights: { value: info.lights },
            per_light: { value: info.per_light ? 1 : 0 },
            light_stride: { value: info.lights },
            coefficient_base: { value: 0 }, // one coefficient texture per object
            lights: { value: lightTexture(info) },
            coefficients: { value: coefficients || EMPTY },
        },
    });
    const mesh = new THREE.Mesh(geometry, material);
    mesh.name = info.name;
    mesh.frustumCulled = false;
    mesh.userData = info;
    return mesh;
}

export async function loadFit(url) {
    const gltf = await new GLTFLoader().loadAsync(url);
    const extras = gltf.scene.userData || {};
    if (extras.format !== FORMAT || extras.version !== VERSION) {
        throw new Error(`${url} is not a ${FORMAT} version ${VERSION} file (was it written by 'vlights export'?)`);
    }
    const sources = new Map(); // object name -> its mesh (geometry, and the extras in userData)
    gltf.scene.traverse((node) => {
        if (node.isMesh && node.userData && typeof node.userData.name === 'string') sources.set(node.userData.name, node);
    });
    const scene = new THREE.Scene();
    const bounds = new THREE.Box3();
    for (const name of extras.objects) {
        const source = sources.get(name);
        if (!source) throw new Error(`${url}: object '${name}' has no mesh`);
        scene.add(makeObject(source.geometry, source.userData));
        source.geometry.computeBoundingBox();
        bounds.union(source.geometry.boundingBox);
    }
    return { scene, bounds, camera: extras.camera || null, extras };
}

// ------------------------------------------------------------------------------ the page

// display.camera.framing_view: the box seen from its -z side, whole in frame
function framingView(bounds, fov) {
    const centre = bounds.getCenter(new THREE.Vector3());
    const radius = Math.max(0.5 * bounds.getSize(new THREE.Vector3()).length(), 1e-9);
    const distance = radius / Math.sin(THREE.MathUtils.degToRad(fov) / 2) * 1.05;
    return { eye: [centre.x, centre.y, centre.z - distance], look_at: centre.toArray(), up: [0, 1, 0], fov_y_deg: fov };
}

class Walkthrough {
    constructor(canvas, overlay, fit, query) {
        this.canvas = canvas;
        this.overlay = overlay;
        this.fit = fit;
        this.mode = query.mode || 'fitted';
        this.exposure = query.exposure ?? 1.0;
        this.maxLights = Math.max(0, ...fit.scene.children.map((m) => m.userData.lights));
        this.lights = query.lights ?? null; // null: all
        this.samples = query.samples ?? 4;
        this.frames = 0;
        this.frameMs = [];
        this.showHelp = true;

        const start = fit.camera || framingView(fit.bounds, DEFAULT_FOV);
        this.start = {
            eye: query.eye || start.eye, look: query.look || start.look_at,
            up: query.up || start.up || [0, 1, 0], fov: query.fov ?? start.fov_y_deg ?? DEFAULT_FOV,
        };
        this.renderer = new THREE.WebGLRenderer({ canvas, antialias: false, alpha: false, preserveDrawingBuffer: true });
        this.renderer.setPixelRatio(1);
        this.renderer.setClearColor(0x000000, 0); // background 0, as the renderer's; render() clears
        this.gl = this.renderer.getContext();
        this.camera = new THREE.PerspectiveCamera(this.start.fov, 1, 0.1, 10);

        this.tonemap = new THREE.RawShaderMaterial({
            glslVersion: THREE.GLSL3, vertexShader: TONEMAP_VS, fragmentShader: TONEMAP_FS,
            uniforms: { hdr: { value: null }, exposure: { value: this.exposure } }, depthTest: false, depthWrite: false,
        });
        const triangle = new THREE.BufferGeometry();
        triangle.setAttribute('position', new THREE.BufferAttribute(new Float32Array([-1, -1, 0, 3, -1, 0, -1, 3, 0]), 3));
        const quad = new THREE.Mesh(triangle, this.tonemap);
        quad.frustumCulled = false;
        this.screen = new THREE.Scene();
        this.screen.add(quad);
        this.screenCamera = new THREE.OrthographicCamera(-1, 1, 1, -1, 0, 1);

        this.walk = new PointerLockControls(this.camera, canvas);
        this.orbit = new OrbitControls(this.camera, canvas); // it turns the camera to its target: set after it
        this.orbit.enabled = false;
        this.resetCamera();
        this.orbit.addEventListener('change', () => this.invalidate());
        this.walk.addEventListener('change', () => this.invalidate());
        canvas.addEventListener('click', () => { if (!this.orbit.enabled) this.walk.lock(); });
        this.held = new Set();
        window.addEventListener('keydown', (e) => this.key(e, true));
        window.addEventListener('keyup', (e) => this.key(e, false));
        window.addEventListener('resize', () => this.invalidate());
        this.dirty = true;
        this.last = performance.now();
        requestAnimationFrame((t) => this.tick(t));
    }

    resetCamera() {
        const s = this.start;
        this.camera.position.fromArray(s.eye);
        this.camera.up.fromArray(s.up).normalize();
        this.camera.fov = s.fov;
        this.camera.lookAt(new THREE.Vector3(...s.look));
        this.orbit.target.fromArray(s.look);
        this.invalidate();
    }

    invalidate() { this.dirty = true; }

    key(e, down) {
        const k = e.key.length === 1 ? e.key.toLowerCase() : e.key;
        if (down) this.held.add(k); else this.held.delete(k);
        if (!down || e.repeat) return;
        if (k === 'm') this.mode = MODES[(MODES.indexOf(this.mode) + 1) % MODES.length];
        else if (k === 'l') this.lights = this.lights === null ? Math.min(2, this.maxLights) : null;
        else if (k === '+' || k === '=') this.exposure *= 2;
        else if (k === '-' || k === '_') this.exposure *= 0.5;
        else if (k === 'o') {
            this.orbit.enabled = !this.orbit.enabled;
            if (this.orbit.enabled) {
                this.walk.unlock();
                this.orbit.target.copy(this.camera.position).add(this.camera.getWorldDirection(new THREE.Vector3())
                    .multiplyScalar(this.fit.bounds.getSize(new THREE.Vector3()).length() * 0.3));
                this.orbit.update();
            }
        } else if (k === 'r') this.resetCamera();
        else if (k === 'h') this.showHelp = !this.showHelp;
        else return;
        this.invalidate();
    }

    move(dt) {
        const speed = this.fit.bounds.getSize(new THREE.Vector3()).length() * 0.25 * (this.held.has('Shift') ? 4 : 1) * dt;
        let moved = false;
        const h = this.held;
        const step = (d) => { moved = true; return d * speed; };
        if (this.orbit.enabled) return false;
        if (h.has('w')) this.walk.moveForward(step(1));
        if (h.has('s')) this.walk.moveForward(step(-1));
        if (h.has('d')) this.walk.moveRight(step(1));
        if (h.has('a')) this.walk.moveRight(step(-1));
        if (h.has('e')) this.camera.position.addScaledVector(this.camera.up, step(1));
        if (h.has('q')) this.camera.position.addScaledVector(this.camera.up, step(-1));
        return moved;
    }

    // display.renderer.Renderer._matrices: depth range from the scene's bounding sphere
    depthRange() {
        const centre = this.fit.bounds.getCenter(new THREE.Vector3());
        const radius = 0.5 * this.fit.bounds.getSize(new THREE.Vector3()).length() + 1e-9;
        const distance = centre.distanceTo(this.camera.position);
        const far = distance + 2 * radius;
        this.camera.near = Math.max(far * 1e-5, (distance - radius) * 0.5);
        this.camera.far = far;
    }

    target(width, height) {
        if (!this.hdr || this.hdr.width !== width || this.hdr.height !== height || this.hdr.samples !== this.samples) {
            if (this.hdr) this.hdr.dispose();
            this.hdr = new THREE.WebGLRenderTarget(width, height, {
                type: THREE.FloatType, format: THREE.RGBAFormat, samples: this.samples > 1 ? this.samples : 0,
                minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter, depthBuffer: true, generateMipmaps: false,
            });
        }
        return this.hdr;
    }

    draw() {
        const width = Math.max(1, this.canvas.clientWidth);
        const height = Math.max(1, this.canvas.clientHeight);
        if (this.canvas.width !== width || this.canvas.height !== height) this.renderer.setSize(width, height, false);
        this.camera.aspect = width / height;
        this.depthRange();
        this.camera.updateProjectionMatrix();
        for (const mesh of this.fit.scene.children) {
            const u = mesh.material.uniforms;
            const k = this.mode === 'diffuse' ? 0 : mesh.userData.lights;
            u.n_lights.value = this.lights === null ? k : Math.max(0, Math.min(k, this.lights));
            u.eye.value.copy(this.camera.position);
        }
        const hdr = this.target(width, height);
        this.renderer.setRenderTarget(hdr);
        this.renderer.render(this.fit.scene, this.camera);
        this.renderer.setRenderTarget(null);
        this.tonemap.uniforms.hdr.value = hdr.texture;
        this.tonemap.uniforms.exposure.value = this.exposure;
        this.renderer.render(this.screen, this.screenCamera);
        // wait for the GPU, so that the frame time is the frame's and the frame is complete
        this.gl.readPixels(0, 0, 1, 1, this.gl.RGBA, this.gl.UNSIGNED_BYTE, new Uint8Array(4));
    }

    frame() {
        const t0 = performance.now();
        this.draw();
        const ms = performance.now() - t0;
        this.frameMs.push(ms);
        if (this.frameMs.length > 30) this.frameMs.shift();
        this.frames += 1;
        this.status();
        return ms;
    }

    status() {
        const mean = this.frameMs.reduce((a, b) => a + b, 0) / Math.max(1, this.frameMs.length);
        const lights = this.mode === 'diffuse' ? 'none' : (this.lights === null ? `all ${this.maxLights}` : `${this.lights}`);
        let text = `${this.mode} | lights ${lights} | exposure ${this.exposure} | ${this.samples} spp | `
            + `frame ${mean.toFixed(1)} ms (${(1000 / mean).toFixed(0)} fps)`;
        if (this.showHelp) {
            text += '\nclick: mouse look (Esc frees) | W A S D walk, Q E down/up, Shift faster | M fitted/diffuse | '
                + 'L 2/all lights | + - exposure | O orbit/walk | R reset | H hide help';
        }
        this.overlay.textContent = text;
    }

    tick(time) {
        const dt = Math.min(0.1, (time - this.last) / 1000);
        this.last = time;
        if (this.move(dt)) this.invalidate();
        if (this.dirty) {
            this.dirty = false;
            this.frame();
            if (this.frames === 1) document.title = 'rendered';
        }
        requestAnimationFrame((t) => this.tick(t));
    }

    // for scripts: n frames drawn back to back, each waited for; their times in ms
    benchmark(n) {
        const times = [];
        for (let i = 0; i < n; ++i) times.push(this.frame());
        return times;
    }

    state() {
        return {
            mode: this.mode, exposure: this.exposure, lights: this.lights, samples: this.samples, frames: this.frames,
            eye: this.camera.position.toArray(), frameMs: [...this.frameMs],
        };
    }
}

export async function main() {
    const overlay = document.getElementById('status');
    const canvas = document.getElementById('view');
    const t0 = performance.now();
    try {
        const query = parseQuery(window.location.search);
        const fit = await loadFit(query.file);
        const walkthrough = new Walkthrough(canvas, overlay, fit, query);
        window.vlights = {
            walkthrough,
            loadMs: performance.now() - t0,
            state: () => walkthrough.state(),
            benchmark: (n) => walkthrough.benchmark(n),
        };
    } catch (err) {
        overlay.textContent = `error: ${err.message}`;
        overlay.classList.add('error');
        document.title = 'error';
        window.vlights = { error: err.message };
        console.error(err);
    }
}
