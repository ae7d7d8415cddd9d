// The WebGL walkthrough of an exported fit (scene.glb, format "vlights.fit.gltf" v5, v4,
// v3, v2 or v1; display/export.py and docs/formats.md hold the schema).
//
// Shading is fit.npz's formula (version 3) per pixel, as `vlights render --shading
// pixel` draws it, with the renderer's own shader files (display/shaders, which `vlights
// export` copies into shaders/ and this page fetches; the fit's emitter quadrature as
// #define lines in shading.js): the emitted colour, plus
//   - the virtual lights: for each light k, pow(dot(n, h), shininess_k) * rgb_k *
//     coefficient_k, h the half vector of the light direction normalize(xyz - w x) and
//     the eye direction, the lobe cut to 0 where (1 - dot(n, h)) * shininess > 30;
//     coefficients shared by the lights (the vertex attribute _SPECULAR) or one per
//     light (_SPECULAR_k, read from a texture by vertex id);
//   - the reflection probe: the per-vertex weight (_PROBE) times the specular albedo
//     S(n . w) times the box-projected look-up of the octahedral map in the mirror
//     direction (a texture per object);
//   - the emitters' glossy highlights: each emitter part (sphere or convex polygon, the
//     table in the scene's extras) integrated against the object's lobe per pixel, or
//     a delta part's (a point, a spot, a direction: a v5 file) lobe at its one
//     direction, times the fraction of the part the vertices see (_VISIBILITY_j, a texture);
//   - a textured object's diffuse term (textured.glsl, compiled in with #define
//     VL_TEXTURED): kd * texture(uv) / pi * E per pixel, uv (TEXCOORD_0) and the
//     irradiance E (_IRRADIANCE) interpolated, the image the material's base colour
//     texture (decoded from sRGB by the GPU, bilinear, repeating, mipmapped), in both
//     modes (the diffuse mode is the emitted colour and this term);
//   - where no object is, the environment (a version 4 or 5 file: the light from outside the
//     scene), in both modes: background_vertex.glsl and background_fragment.glsl, the
//     renderer's (display.renderer.Renderer._draw_background), drawn after the objects
//     into the same float framebuffer with the depth test "<=" at the far plane, its
//     image (float32 texels in a bufferView of the file) a float texture, bilinear,
//     repeating in u, clamped in v, row 0 (the zenith) at t = 0 as the renderer uploads it.
// Per-light coefficients and visibilities are blended from the triangle's three
// vertices by barycentrics, as the renderer's geometry-shader program does: such
// objects are drawn with one vertex per triangle corner carrying the triangle's vertex
// ids and the corner's barycentrics. The scene is drawn in linear radiance into a float
// framebuffer (MSAA, `samples` per pixel), then exposure, clipping and sRGB map it to
// the screen with tonemap.glsl, the renderer's and the window's (display.renderer.tonemap).
//
// Sides and depth, as display.renderer draws them (its docstring, "Sides and depth"):
// surfaces are one-sided, so each object's front faces are drawn first (FrontSide), then
// every back face black (back_fragment.glsl, BackSide, renderOrder 1) with a strict depth
// test ("<"): a one-sided wall seen from behind is a black occluder, and a two-sided
// wall's back copy wins over its front copy's back. Depth is reversed Z where the
// browser has EXT_clip_control (three.js's reversedDepthBuffer: near at 1, here an
// infinite far plane at 0, DepthCamera) into a float depth buffer (a FloatType
// DepthTexture on the render target: DEPTH_COMPONENT32F), the near plane from the
// scene's box and the eye (depthRange: display.renderer.depth_range); elsewhere the
// conventional range into 24 bits, a larger near plane and the back faces pushed back
// by a polygon offset, as the renderer does without clip control.
//
// URL query (all optional): eye=x,y,z look=x,y,z up=x,y,z fov=deg (vertical; without it,
// the scene camera's field of view, kept along its axis at any window size) mode=fitted|diffuse
// exposure=e lights=n samples=1|2|4 off=emitters,probe,lights (any of them: those parts
// of the model are not drawn, as `vlights render --off`) file=scene.glb maxtexture=n (the
// largest texture side the page may use: the GPU's MAX_TEXTURE_SIZE, or n if smaller, to
// see what a smaller GPU shows). document.title becomes "rendered" after the first
// complete frame ("error" if the scene cannot be shown).
//
// Texture limits: each object's per-light coefficients and its emitters' visibility are
// textures TEXTURE_WIDTH (4096) wide, a row per 4096 values, its lights 2 x K, its probe
// M x M (textureNeeds); before any is made, every object's are checked against the
// GPU's MAX_TEXTURE_SIZE (and the emitter table and the environment's image too), and a
// texture too large is refused on the page in one line naming the object and the limit
// (WebGL does not make a texture over the limit, INVALID_VALUE, and the shader would read
// zeros: the object drawn wrong, silently). The export warns of objects that need more
// than 4096 (display/export_limits.py).
//
// Keys: W A S D walk, Q E down / up, Shift faster, mouse look after a click (Esc frees
// the mouse); M fitted / diffuse-only; L two lights / all lights; 1 2 3 switch the
// emitters' highlights / the probe / the lights off and on; + - exposure x2 / x0.5;
// O orbit / walk; R back to the start camera; H hides this help.

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { PointerLockControls } from 'three/addons/controls/PointerLockControls.js';
// written by `vlights export`: the #define lines of display/glsl.py for this fit's
// emitter nodes, and the constants of the textures' layout
import { ALBEDO_POINTS, DEFINES, EMITTER_NODES, LTC_SIZE, LTC_TABLE, MAX_OBJECT_PARTS, TABLE_WIDTH, TEXTURE_WIDTH } from './shading.js';

const FORMAT = 'vlights.fit.gltf';
const VERSIONS = [1, 2, 3, 4, 5, 6, 7, 8]; // what this page reads (display.export.READS)
const MODES = ['fitted', 'diffuse'];
const PARTS = ['lights', 'probe', 'emitters']; // fitting.model.PARTS: the parts of the model that may be off
const PART_KEYS = { 1: 'emitters', 2: 'probe', 3: 'lights' }; // as the walkthrough window's keys
const DEFAULT_FOV = 39.3; // display.camera.framing_view
// display.renderer.NEAR_FRACTION and BACK_FACE_OFFSET: the least near plane, a fraction of
// the far distance, with reversed Z (true) and without; the back faces' polygon offset
// (factor, units) without
const NEAR_FRACTION = { true: 1e-5, false: 1e-3 };
const BACK_FACE_OFFSET = [1, 4];
export const REVERSED_Z = '#define VL_REVERSED_Z\n'; // the background at depth 0 (background_vertex.glsl)

// -------------------------------------------------------------------------------- shaders

// The renderer's own shader files (display/shaders, copied into shaders/ by `vlights
// export`), fetched once each. A stage's source is es_header.glsl (precisions,
// VL_TRIANGLE: this page's vertices carry the triangle's ids and barycentrics), then
// DEFINES (and, for a textured object's program, TEXTURED), then its file with each
// `#include "file"` line replaced by that file's text, each file once
// (display.glsl.resolve does the same); three.js writes `#version 300 es`.
const INCLUDE = /^#include "([^"]+)"[ \t]*$/m;
const shaderFiles = new Map(); // name -> Promise of its text

function shaderFile(name) {
    if (!shaderFiles.has(name)) {
        shaderFiles.set(name, fetch(new URL(`shaders/${name}`, import.meta.url)).then((response) => {
            if (!response.ok) throw new Error(`shaders/${name}: ${response.status} ${response.statusText} (export the page again)`);
            return response.text();
        }));
    }
    return shaderFiles.get(name);
}

// `name` with its includes resolved (split on a capturing pattern: text, file, text, ...)
export async function resolveShader(name, seen = new Set()) {
    if (seen.has(name)) return '';
    seen.add(name);
    const pieces = (await shaderFile(name)).split(new RegExp(INCLUDE.source, 'gm'));
    let text = '';
    for (let i = 0; i < pieces.length; ++i) text += i % 2 ? await resolveShader(pieces[i], seen) : pieces[i];
    return text;
}

export const TEXTURED = '#define VL_TEXTURED\n'; // display.glsl.defines(extra=("VL_TEXTURED",))'s last line
// a masked object's programs: cutout.glsl's alpha test on its image's alpha (a version 8 file)
export const CUTOUT = '#define VL_CUTOUT\n#define VL_CUTOUT_ALPHA\n';

// `extra`: #define lines after DEFINES (TEXTURED, or none)
export async function stageSource(name, extra = '') {
    return (await shaderFile('es_header.glsl')) + DEFINES + extra + (await resolveShader(name));
}

// the fitted model per pixel (as `vlights render --shading pixel`), the backs' fragment
// stage (after web_vertex.glsl) and the tone map; with `textured`, also the fitted program
// of textured objects (#define VL_TEXTURED); with `masked`, the masked objects' fitted and
// back programs (CUTOUT); with `environment`, the background's program (#define
// VL_REVERSED_Z where `reversed`)
async function loadShaders(textured, masked, environment, reversed) {
    const names = ['web_vertex.glsl', 'fitted_fragment.glsl', 'back_fragment.glsl', 'full_screen_vertex.glsl', 'tonemap_fragment.glsl'];
    const [fittedVertex, fittedFragment, backFragment, screenVertex, tonemapFragment] = await Promise.all(names.map((n) => stageSource(n)));
    const shaders = { fittedVertex, fittedFragment, backFragment, screenVertex, tonemapFragment };
    if (textured) {
        [shaders.texturedVertex, shaders.texturedFragment] = await Promise.all(
            ['web_vertex.glsl', 'fitted_fragment.glsl'].map((n) => stageSource(n, TEXTURED)));
    }
    if (masked) {
        [shaders.maskedVertex, shaders.maskedFragment, shaders.maskedBackFragment] = await Promise.all(
            ['web_vertex.glsl', 'fitted_fragment.glsl', 'back_fragment.glsl'].map((n) => stageSource(n, TEXTURED + CUTOUT)));
    }
    if (environment) {
        [shaders.backgroundVertex, shaders.backgroundFragment] = await Promise.all(
            ['background_vertex.glsl', 'background_fragment.glsl'].map((n) => stageSource(n, reversed ? REVERSED_Z : '')));
    }
    return shaders;
}

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
    if (q.has('off')) {
        const off = q.get('off').split(',').filter((p) => p !== '');
        const bad = off.find((p) => !PARTS.includes(p));
        if (bad !== undefined) throw new Error(`off: want parts among ${PARTS.join(',')}, got '${bad}'`);
        state.off = off;
    }
    state.maxTexture = num('maxtexture', (v) => Number.isInteger(v) && v >= 1, 'a whole number >= 1');
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

// RGBA texels, TEXTURE_WIDTH wide, value i at texel (i % width, i / width): the layout of
// the renderer's float textures (display.renderer._float_texture); fill(data) writes the values
function wideTexture(count, fill) {
    const height = Math.max(1, Math.ceil(count / TEXTURE_WIDTH));
    const data = new Float32Array(TEXTURE_WIDTH * height * 4);
    fill(data);
    return floatTexture(data, TEXTURE_WIDTH, height);
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
    return wideTexture(v * k, (data) => {
        for (let light = 0; light < k; ++light) {
            const a = attributes[`_specular_${light}`].array;
            for (let i = 0; i < v; ++i) {
                const t = 4 * (i * k + light);
                data[t] = a[3 * i];
                data[t + 1] = a[3 * i + 1];
                data[t + 2] = a[3 * i + 2];
            }
        }
    });
}

// the visibility of every vertex, part i of vertex v in the red channel of texel v * P + i
// (the renderer's layout, display.glsl visibility_at, with visibility_base 0); from the
// attributes _VISIBILITY_j, which hold parts 3 j, 3 j + 1, 3 j + 2
function visibilityTexture(attributes, v, parts, where) {
    const columns = [];
    for (let j = 0; 3 * j < parts; ++j) columns.push(requireAttribute({ attributes }, `_visibility_${j}`, where).array);
    return wideTexture(v * parts, (data) => {
        for (let i = 0; i < v; ++i) {
            for (let part = 0; part < parts; ++part) {
                data[4 * (i * parts + part)] = columns[Math.floor(part / 3)][3 * i + (part % 3)];
            }
        }
    });
}

// the probe's M x M texels, texel (i, j) = column i, row j (the renderer's atlas holds one
// object's block at rows probe_row .. probe_row + M - 1; here every object has its own, probe_row 0)
function probeTexture(probe, where) {
    const m = probe.size;
    if (!Number.isInteger(m) || m < 1 || probe.texels.length !== 3 * m * m || probe.albedo.length !== ALBEDO_POINTS) {
        throw new Error(`${where}: its probe needs 'size' M, M * M * 3 'texels' and ${ALBEDO_POINTS} 'albedo' values`);
    }
    const data = new Float32Array(4 * m * m);
    for (let t = 0; t < m * m; ++t) data.set(probe.texels.slice(3 * t, 3 * t + 3), 4 * t);
    return floatTexture(data, m, m);
}

// The indices of the scene's emitter parts an object's highlight draws: those its
// extras' highlight.parts name (version 6: checked against the scene's `count`), else
// all of them; none without a highlight
export function drawnParts(info, count) {
    if (!info.highlight) return [];
    const named = info.highlight.parts;
    if (named === undefined) return [...Array(count).keys()];
    if (!Array.isArray(named) || new Set(named).size !== named.length
        || !named.every((i) => Number.isInteger(i) && i >= 0 && i < count)) {
        throw new Error(`object '${info.name}': its highlight's parts must name distinct parts of the scene's ${count}`);
    }
    return named;
}

// the emitter parts' table (display.glsl.emitter_table, written by export into the
// scene's extras): row i = part i, TABLE_WIDTH RGBA texels; at least one row
function emitterTable(rows) {
    const data = new Float32Array(TABLE_WIDTH * 4 * Math.max(rows.length, 1));
    rows.forEach((row, i) => {
        if (row.length !== TABLE_WIDTH * 4) throw new Error(`emitter table row ${i}: want ${TABLE_WIDTH * 4} numbers, got ${row.length}`);
        data.set(row, TABLE_WIDTH * 4 * i);
    });
    return floatTexture(data, TABLE_WIDTH, Math.max(rows.length, 1));
}

function requireAttribute(geometry, name, where, size = 3, gltfName = name.toUpperCase()) {
    const a = geometry.attributes[name];
    if (!a || a.itemSize !== size) throw new Error(`${where}: vertex attribute ${gltfName} (VEC${size}) is missing`);
    return a;
}

// The triangle geometry of one object for the shader: indexed when its coefficients are
// shared and it has no highlight; with per-light coefficients or the emitters'
// highlights, one vertex per triangle corner carrying the triangle's vertex ids and the
// corner's barycentrics (what the renderer's geometry shader hands its fragments). A
// textured object's geometry has its uvs ('uv': glTF's TEXCOORD_0, v down the image) and
// its irradiance as well.
function objectGeometry(source, info) {
    const where = `object '${info.name}'`;
    const position = requireAttribute(source, 'position', where);
    const normal = requireAttribute(source, 'normal', where);
    const emitted = requireAttribute(source, '_emitted', where);
    const v = position.count;
    const k = info.lights;
    if (!source.index) throw new Error(`${where}: the mesh has no indices`);
    const faces = source.index.array;
    const zeros = () => new THREE.BufferAttribute(new Float32Array(3 * v), 3);
    const specular = k > 0 && !info.per_light ? requireAttribute(source, '_specular', where) : zeros();
    const probe = info.probe ? requireAttribute(source, '_probe', where) : zeros();
    const coefficients = info.per_light ? coefficientTexture(source.attributes, v, k) : null;
    if (info.per_light) for (let i = 0; i < k; ++i) requireAttribute(source, `_specular_${i}`, where);
    const src = { position, normal, emitted, specular, probe };
    if (info.textured) {
        src.uv = requireAttribute(source, 'uv', where, 2, 'TEXCOORD_0');
        src.irradiance = requireAttribute(source, '_irradiance', where);
    }
    if (!info.per_light && !info.highlight) {
        const g = new THREE.BufferGeometry();
        g.setIndex(new THREE.BufferAttribute(faces, 1));
        for (const [key, attribute] of Object.entries(src)) g.setAttribute(key, attribute);
        g.setAttribute('vertices', zeros());
        g.setAttribute('bary', zeros());
        return { geometry: g, coefficients };
    }
    const corners = faces.length;
    const out = { vertices: new Float32Array(3 * corners), bary: new Float32Array(3 * corners) };
    for (const [key, attribute] of Object.entries(src)) out[key] = new Float32Array(attribute.itemSize * corners);
    for (let c = 0; c < corners; ++c) {
        const vertex = faces[c];
        const tri = c - (c % 3);
        for (const [key, attribute] of Object.entries(src)) {
            const n = attribute.itemSize;
            for (let i = 0; i < n; ++i) out[key][n * c + i] = attribute.array[n * vertex + i];
        }
        out.vertices.set([faces[tri], faces[tri + 1], faces[tri + 2]], 3 * c);
        out.bary[3 * c + (c % 3)] = 1;
    }
    const g = new THREE.BufferGeometry();
    for (const [key, array] of Object.entries(out)) {
        g.setAttribute(key, new THREE.BufferAttribute(array, array.length / corners));
    }
    return { geometry: g, coefficients };
}

// A textured object's image: the material's base colour texture as GLTFLoader made it
// (an 8-bit RGBA ImageBitmap; flipY false, so the image's top row lies at t = 0, where
// glTF's v, down the image, puts it). Its colour space sRGB makes three.js store it as
// SRGB8_ALPHA8, which the GPU decodes to linear when it samples, before filtering: the
// one decode (the shader has none, as the renderer's float texture needs none). Repeating,
// mipmapped, as the file's sampler and the renderer's texture.
function diffuseTexture(material, info, where) {
    const map = material && material.map;
    if (!map || !map.isTexture) throw new Error(`${where}: textured, but its material has no base colour texture`);
    const kd = info.textured.kd;
    if (!Array.isArray(kd) || kd.length !== 3 || !kd.every(Number.isFinite)) {
        throw new Error(`${where}: 'textured' needs 'kd' [r, g, b]`);
    }
    map.colorSpace = THREE.SRGBColorSpace;
    map.format = THREE.RGBAFormat;
    map.type = THREE.UnsignedByteType;
    map.flipY = false;
    map.wrapS = THREE.RepeatWrapping;
    map.wrapT = THREE.RepeatWrapping;
    map.magFilter = THREE.LinearFilter;
    map.minFilter = THREE.LinearMipmapLinearFilter;
    map.generateMipmaps = true;
    return map;
}

const EMPTY = floatTexture(new Float32Array(4), 1, 1);
// the microfacet lobes' table (ltc.glsl; shading.js's LTC_TABLE: little-endian float32 in base64), made where one draws
let ltcTexture = null;
function ltcTable() {
    if (ltcTexture === null) {
        const bytes = Uint8Array.from(atob(LTC_TABLE), (c) => c.charCodeAt(0));
        ltcTexture = floatTexture(new Float32Array(bytes.buffer), 2 * LTC_SIZE, 2 * LTC_SIZE);
    }
    return ltcTexture;
}

// ------------------------------------------------------------------------- texture limits

// The largest texture side this page may use: the GPU's MAX_TEXTURE_SIZE, or the query's
// maxtexture where that is smaller
export function textureLimit(gl, query = {}) {
    const max = gl.getParameter(gl.MAX_TEXTURE_SIZE);
    return query.maxTexture === undefined ? max : Math.min(max, query.maxTexture);
}

// The float textures makeObject makes for an object of `vertices` vertices whose
// highlight draws `parts` emitter parts, as [{ what, width, height }]: its lights
// (lightTexture), its per-light coefficients and its emitters' visibility (wideTexture:
// TEXTURE_WIDTH wide, a row per TEXTURE_WIDTH values), its probe (probeTexture);
// display.export_limits.object_textures lists the same
export function textureNeeds(info, vertices, parts) {
    const k = info.lights;
    const rows = (values) => Math.max(1, Math.ceil(values / TEXTURE_WIDTH));
    const count = (n) => n.toLocaleString('en-US');
    const needs = [{ what: `its ${k} lights`, width: 2, height: Math.max(k, 1) }];
    if (info.per_light && k > 0) {
        needs.push({ what: `its per-light coefficients (${count(vertices)} vertices x ${k} lights)`, width: TEXTURE_WIDTH, height: rows(vertices * k) });
    }
    if (parts > 0) {
        needs.push({ what: `its emitters' visibility (${count(vertices)} vertices x ${parts} parts)`, width: TEXTURE_WIDTH, height: rows(vertices * parts) });
    }
    if (info.probe) needs.push({ what: 'its probe', width: info.probe.size, height: info.probe.size });
    return needs;
}

// An Error naming `owner` and the limit for the first of `needs` larger than `max` texels
// on a side; null if all fit
export function textureRefusal(owner, needs, max) {
    const t = needs.find((n) => Math.max(n.width, n.height) > max);
    if (!t) return null;
    return new Error(`${owner} needs a ${t.width} x ${t.height} texture for ${t.what}; this browser's textures are `
        + `at most ${max} x ${max} (MAX_TEXTURE_SIZE), so it cannot be drawn here`);
}

function checkTextures(owner, needs, max) {
    const refusal = textureRefusal(owner, needs, max);
    if (refusal) throw refusal;
}

// One object's mesh and material: the uniforms and textures display.renderer's
// _bind_fitted, _bind_highlight and _bind_probe set (each object with its own textures,
// so every base and row is 0), and for a textured object (VL_TEXTURED) the uniforms of
// textured.glsl. userData.parts: the emitter parts its highlight draws (0: none),
// userData.probeSize its probe's M (0: none). `node`: the glTF's mesh.
function makeObject(node, info, fit) {
    const where = `object '${info.name}'`;
    const source = node.geometry;
    const { geometry, coefficients } = objectGeometry(source, info);
    const textured = info.textured ? diffuseTexture(node.material, info, where) : null;
    const masked = textured !== null && isMasked(node.material);
    const v = source.attributes.position.count;
    // the parts its highlight draws: those its extras name (version 6), else all the scene's
    const drawn = drawnParts(info, fit.parts.length);
    const parts = drawn.length;
    const h = info.highlight || { ks: [0, 0, 0], exponent: 0 };
    const probe = info.probe || null;
    let own = 0; // bit i: its part i belongs to this object (it does not see itself)
    drawn.forEach((index, i) => { if (fit.parts[index].source === info.name) own |= 1 << i; });
    const table = info.highlight && info.highlight.parts ? emitterTable(drawn.map((i) => fit.tableRows[i])) : fit.emitterTable;
    const material = new THREE.RawShaderMaterial({
        glslVersion: THREE.GLSL3,
        vertexShader: masked ? fit.shaders.maskedVertex : textured ? fit.shaders.texturedVertex : fit.shaders.fittedVertex,
        fragmentShader: masked ? fit.shaders.maskedFragment : textured ? fit.shaders.texturedFragment : fit.shaders.fittedFragment,
        side: THREE.FrontSide, // the back faces: its child, black (backMaterial)
        depthFunc: THREE.LessDepth, // strict, as the renderer's (reversed: ">", three.js turns it)
        uniforms: {
            eye: { value: new THREE.Vector3() },
            flat_colour: { value: new THREE.Vector4(0, 0, 0, 0) }, // w = 0: shaded (the renderer's masks set it)
            // the virtual lights
            n_lights: { value: info.lights },
            per_light: { value: info.per_light ? 1 : 0 },
            light_stride: { value: info.lights },
            coefficient_base: { value: 0 }, // one coefficient texture per object
            lights: { value: lightTexture(info) },
            coefficients: { value: coefficients || EMPTY },
            // the emitters' highlights
            emitter_table: { value: table },
            n_parts: { value: parts },
            own_parts: { value: own },
            emitter_ks: { value: new THREE.Vector3(...(h.lobe ? h.lobe.ks : h.ks)) },
            emitter_exponent: { value: h.exponent },
            emitter_f0: { value: new THREE.Vector3(...(h.lobe ? h.lobe.f0 : h.fresnel || [-1, -1, -1])) },
            // a microfacet lobe (a version 7 file): linearly transformed cosines
            emitter_lobe: { value: h.lobe ? h.lobe.code : 0 },
            emitter_alpha: { value: h.lobe ? h.lobe.alpha : 0 },
            ltc_table: { value: h.lobe ? ltcTable() : EMPTY },
            visibility: { value: parts ? visibilityTexture(source.attributes, v, parts, where) : EMPTY },
            visibility_base: { value: 0 }, // one visibility texture per object
            // the reflection probe
            probes: { value: probe ? probeTexture(probe, where) : EMPTY },
            probe_size: { value: probe ? probe.size : 0 },
            probe_row: { value: 0 }, // one probe texture per object
            probe_centre: { value: new THREE.Vector3(...(probe ? probe.centre : [0, 0, 0])) },
            probe_lo: { value: new THREE.Vector3(...(probe ? probe.box[0] : [0, 0, 0])) },
            probe_hi: { value: new THREE.Vector3(...(probe ? probe.box[1] : [0, 0, 0])) },
            probe_albedo: { value: new Float32Array(probe ? probe.albedo : ALBEDO_POINTS) },
            // a textured object's diffuse term
            ...(textured ? { diffuse_texture: { value: textured }, texture_kd: { value: new THREE.Vector3(...info.textured.kd) } } : {}),
            // a masked object's cut-out: its image's alpha
            ...(masked ? { cutout_texture: { value: textured } } : {}),
        },
    });
    const mesh = new THREE.Mesh(geometry, material);
    mesh.name = info.name;
    mesh.frustumCulled = false;
    mesh.userData = { ...info, parts, probeSize: probe ? probe.size : 0 };
    const back = new THREE.Mesh(geometry, masked ? maskedBackMaterial(fit, textured) : fit.backMaterial);
    back.name = `${info.name}: its back faces`;
    back.frustumCulled = false;
    back.renderOrder = 1; // after every front (renderOrder 0)
    mesh.add(back);
    return mesh;
}

// The back faces of every object (display.renderer's back pass): black, with a strict
// depth test after every front, so that a front at the same depth wins; where depth is
// coarse (no reversed Z) pushed back by BACK_FACE_OFFSET. Its vertex stage is the
// objects' own (web_vertex.glsl), so that fronts and backs rasterise alike.
function backMaterial(shaders, reversed) {
    return new THREE.RawShaderMaterial({
        glslVersion: THREE.GLSL3, vertexShader: shaders.fittedVertex, fragmentShader: shaders.backFragment,
        side: THREE.BackSide, depthFunc: THREE.LessDepth,
        polygonOffset: !reversed, polygonOffsetFactor: BACK_FACE_OFFSET[0], polygonOffsetUnits: BACK_FACE_OFFSET[1],
    });
}

// A masked object's back faces: black with its holes (cutout.glsl on its image's alpha)
function maskedBackMaterial(fit, image) {
    const material = fit.backMaterial.clone();
    material.vertexShader = fit.shaders.maskedVertex;
    material.fragmentShader = fit.shaders.maskedBackFragment;
    material.uniforms = { cutout_texture: { value: image } };
    return material;
}

// Whether a glTF material is masked: alphaMode MASK, which GLTFLoader turns into alphaTest
// (the cut-off, > 0). The page's alpha test is the renderer's (cutout.glsl), so three.js's
// own is turned off.
function isMasked(material) {
    if (!material || !(material.alphaTest > 0)) return false;
    material.alphaTest = 0;
    return true;
}

// ---------------------------------------------------------------------------- environment

// The scene extras' "environment" (a version 4 file) and its image, the float32 texels
// of its bufferView (H * W * 3, little-endian, row 0 the zenith), as
// { width, height, rgb: Float32Array, rotation: Matrix3 (world from environment), scale }
async function readEnvironment(gltf, entry, url) {
    const where = `${url}: scene extras 'environment'`;
    const { width, height, bufferView, scale, rotation } = entry;
    if (![width, height].every((n) => Number.isInteger(n) && n >= 1) || !Number.isInteger(bufferView)) {
        throw new Error(`${where} needs whole numbers 'width', 'height' >= 1 and 'bufferView'`);
    }
    const rows = Array.isArray(rotation) && rotation.length === 3 && rotation.every((r) => Array.isArray(r) && r.length === 3) ? rotation.flat() : [];
    if (rows.length !== 9 || !rows.every(Number.isFinite) || !(Number.isFinite(scale) && scale >= 0)) {
        throw new Error(`${where} needs 'rotation' (3 x 3 numbers) and 'scale' >= 0`);
    }
    const bytes = await gltf.parser.getDependency('bufferView', bufferView);
    if (bytes.byteLength !== width * height * 12) {
        throw new Error(`${where}: bufferView ${bufferView} holds ${bytes.byteLength} bytes, not ${height} x ${width} x 3 float32`);
    }
    const view = new DataView(bytes);
    const rgb = new Float32Array(width * height * 3);
    for (let i = 0; i < rgb.length; ++i) rgb[i] = view.getFloat32(4 * i, true); // little-endian whatever the machine
    return { width, height, rgb, rotation: new THREE.Matrix3().set(...rows), scale };
}

// The environment's image as the texture background_fragment.glsl samples: RGBA (alpha 1),
// row 0 at t = 0 (flipY false, as the renderer uploads it), bilinear, repeating in s,
// clamped in t, no mipmaps. Float32 where the GPU filters it (OES_texture_float_linear,
// the renderer's 'f4'); else half floats (filterable in every WebGL2), clamped to their
// largest value, 65504, with a warning.
export function environmentTexture(rgb, width, height, floatLinear) {
    const count = width * height;
    const data = floatLinear ? new Float32Array(4 * count) : new Uint16Array(4 * count);
    const one = floatLinear ? 1 : THREE.DataUtils.toHalfFloat(1);
    for (let i = 0; i < count; ++i) {
        for (let c = 0; c < 3; ++c) {
            const value = rgb[3 * i + c];
            data[4 * i + c] = floatLinear ? value : THREE.DataUtils.toHalfFloat(Math.min(value, 65504));
        }
        data[4 * i + 3] = one;
    }
    if (!floatLinear) console.warn('this GPU does not filter float32 textures: the environment is drawn from half floats');
    const texture = new THREE.DataTexture(data, width, height, THREE.RGBAFormat, floatLinear ? THREE.FloatType : THREE.HalfFloatType);
    texture.flipY = false;
    texture.wrapS = THREE.RepeatWrapping;
    texture.wrapT = THREE.ClampToEdgeWrapping;
    texture.minFilter = THREE.LinearFilter;
    texture.magFilter = THREE.LinearFilter;
    texture.generateMipmaps = false;
    texture.needsUpdate = true;
    return texture;
}

// one triangle over the viewport: three vertices, which the shaders place by gl_VertexID
function fullScreenTriangle() {
    const triangle = new THREE.BufferGeometry();
    triangle.setAttribute('position', new THREE.BufferAttribute(new Float32Array([-1, -1, 0, 3, -1, 0, -1, 3, 0]), 3));
    return triangle;
}

// The background (display.renderer.Renderer._draw_background): one triangle at the far
// plane drawn after the objects and their backs (renderOrder), where the depth test "<="
// (reversed: ">=") lets it through, writing no depth; its camera uniforms set each frame
// (Walkthrough.draw).
function backgroundMesh(environment, shaders, floatLinear) {
    const material = new THREE.RawShaderMaterial({
        glslVersion: THREE.GLSL3, vertexShader: shaders.backgroundVertex, fragmentShader: shaders.backgroundFragment,
        side: THREE.DoubleSide, depthTest: true, depthWrite: false, depthFunc: THREE.LessEqualDepth,
        uniforms: {
            environment: { value: environmentTexture(environment.rgb, environment.width, environment.height, floatLinear) },
            env_rotation: { value: environment.rotation },
            env_scale: { value: environment.scale },
            cam_right: { value: new THREE.Vector3() },
            cam_up: { value: new THREE.Vector3() },
            cam_forward: { value: new THREE.Vector3() },
            cam_extent: { value: new THREE.Vector2() },
            viewport: { value: new THREE.Vector2() },
        },
    });
    const mesh = new THREE.Mesh(fullScreenTriangle(), material);
    mesh.name = 'environment';
    mesh.frustumCulled = false;
    mesh.renderOrder = 2; // after every object (renderOrder 0) and every back (1)
    return mesh;
}

// ---------------------------------------------------------------------------------- fit

// `maxTexture`: the largest texture side the page may use (textureLimit); `reversed`:
// the renderer draws with reversed Z (the background's shader depends on it)
export async function loadFit(url, maxTexture, reversed = false) {
    const gltf = await new GLTFLoader().loadAsync(url);
    const extras = gltf.scene.userData || {};
    if (extras.format !== FORMAT || !VERSIONS.includes(extras.version)) {
        throw new Error(`${url} is not a ${FORMAT} version ${VERSIONS.join(' or ')} file (was it written by 'vlights export'?)`);
    }
    const parts = extras.emitters || [];
    const nodes = extras.emitter_nodes ?? EMITTER_NODES;
    if (parts.length && nodes !== EMITTER_NODES) {
        throw new Error(`${url}: its emitters are drawn with ${nodes} nodes, this page's shading.js with ${EMITTER_NODES} (export it again)`);
    }

    const sources = new Map(); // object name -> its mesh (geometry, material, and the extras in userData)
    gltf.scene.traverse((node) => {
        if (node.isMesh && node.userData && typeof node.userData.name === 'string') sources.set(node.userData.name, node);
    });
    // every texture's size checked before any is made
    checkTextures('the scene', [{ what: `its emitter table (${parts.length} parts)`, width: TABLE_WIDTH, height: Math.max(parts.length, 1) }], maxTexture);
    for (const name of extras.objects) {
        const source = sources.get(name);
        if (!source) throw new Error(`${url}: object '${name}' has no mesh`);
        const info = source.userData;
        const vertices = source.geometry.attributes.position ? source.geometry.attributes.position.count : 0;
        // own_parts, an int, is a bit mask of the parts an object draws
        const drawn = drawnParts(info, parts.length).length;
        if (drawn > MAX_OBJECT_PARTS) throw new Error(`${url}: object '${name}' draws ${drawn} emitter parts; the shader draws at most ${MAX_OBJECT_PARTS}`);
        checkTextures(`object '${name}'`, textureNeeds(info, vertices, drawn), maxTexture);
    }
    const textured = [...sources.values()].some((node) => node.userData.textured);
    const masked = [...sources.values()].some((node) => node.userData.textured && node.material && node.material.alphaTest > 0);
    const environment = extras.version >= 4 && extras.environment ? await readEnvironment(gltf, extras.environment, url) : null;
    if (environment) {
        checkTextures('the scene', [{ what: 'its environment', width: environment.width, height: environment.height }], maxTexture);
    }
    const shaders = await loadShaders(textured, masked, environment, reversed);
    const tableRows = extras.emitter_table || [];
    const fit = { parts, tableRows, emitterTable: emitterTable(tableRows), shaders, backMaterial: backMaterial(shaders, reversed) };
    const scene = new THREE.Scene();
    const objects = [];
    const bounds = new THREE.Box3();
    for (const name of extras.objects) {
        const source = sources.get(name);
        objects.push(makeObject(source, source.userData, fit));
        scene.add(objects.at(-1));
        source.geometry.computeBoundingBox();
        bounds.union(source.geometry.boundingBox);
    }
    // scene: the objects, then (added by the Walkthrough, which knows the GPU) the background
    return { scene, objects, bounds, camera: extras.camera || null, extras, shaders: fit.shaders, environment };
}

// ------------------------------------------------------------------------------ the page

// radiosity.files.camera.fov_y_deg: the vertical field of view of a width x height image
// whose field of view along axis (x, y, diagonal, smaller, larger: Mitsuba's fov_axis) is fov
const FOV_AXES = ['x', 'y', 'diagonal', 'smaller', 'larger'];
function verticalFov(fov, axis, width, height) {
    if (axis === 'smaller') axis = width < height ? 'x' : 'y';
    else if (axis === 'larger') axis = width > height ? 'x' : 'y';
    const ratio = { x: height / width, y: 1, diagonal: height / Math.hypot(width, height) }[axis];
    return THREE.MathUtils.radToDeg(2 * Math.atan(Math.tan(THREE.MathUtils.degToRad(fov) / 2) * ratio));
}

// display.camera.framing_view: the box seen from its -z side, whole in frame
function framingView(bounds, fov) {
    const centre = bounds.getCenter(new THREE.Vector3());
    const radius = Math.max(0.5 * bounds.getSize(new THREE.Vector3()).length(), 1e-9);
    const distance = radius / Math.sin(THREE.MathUtils.degToRad(fov) / 2) * 1.05;
    return { eye: [centre.x, centre.y, centre.z - distance], look_at: centre.toArray(), up: [0, 1, 0], fov_y_deg: fov };
}

// The page's camera: three.js's perspective (its fov and aspect), with the depth of
// display.renderer.Depth.projection: with reversed Z (three.js's own when the renderer
// has reversedDepthBuffer) the far plane at infinity, clip z = near, so that depth =
// near / distance, computed without cancellation; otherwise three.js's near to far.
export class DepthCamera extends THREE.PerspectiveCamera {
    updateProjectionMatrix() {
        super.updateProjectionMatrix();
        if (this.reversedDepth) {
            const e = this.projectionMatrix.elements; // column-major: row 2 is e[2], e[6], e[10], e[14]
            e[10] = 0;
            e[14] = this.near;
            this.projectionMatrixInverse.copy(this.projectionMatrix).invert();
        }
    }
}

// display.renderer.depth_range: (near, far) of a view from `eye` (Vector3) of a scene in
// the box `bounds` (Box3): far the distance to the box's farthest corner, near half the
// distance to the box, at least `fraction` of far
export function depthRange(bounds, eye, fraction) {
    const corner = new THREE.Vector3(
        Math.max(Math.abs(bounds.min.x - eye.x), Math.abs(bounds.max.x - eye.x)),
        Math.max(Math.abs(bounds.min.y - eye.y), Math.abs(bounds.max.y - eye.y)),
        Math.max(Math.abs(bounds.min.z - eye.z), Math.abs(bounds.max.z - eye.z)));
    const far = Math.max(corner.length(), 1e-30);
    const outside = new THREE.Vector3(
        Math.max(bounds.min.x - eye.x, eye.x - bounds.max.x, 0),
        Math.max(bounds.min.y - eye.y, eye.y - bounds.max.y, 0),
        Math.max(bounds.min.z - eye.z, eye.z - bounds.max.z, 0)).length();
    return [Math.max(0.5 * outside, fraction * far), far];
}

class Walkthrough {
    // renderer: the canvas's THREE.WebGLRenderer, made by main before loadFit checked the
    // fit's textures against its limit
    constructor(canvas, overlay, fit, query, renderer) {
        this.canvas = canvas;
        this.overlay = overlay;
        this.fit = fit;
        this.mode = query.mode || 'fitted';
        this.exposure = query.exposure ?? 1.0;
        this.maxLights = Math.max(0, ...fit.objects.map((m) => m.userData.lights));
        this.lights = query.lights ?? null; // null: all
        this.samples = query.samples ?? 4;
        this.off = new Set(query.off || []); // the parts of the model not drawn (keys 1, 2, 3)
        this.frames = 0;
        this.frameMs = [];
        this.showHelp = true;

        const start = fit.camera || framingView(fit.bounds, DEFAULT_FOV);
        this.start = {
            eye: query.eye || start.eye, look: query.look || start.look_at,
            up: query.up || start.up || [0, 1, 0], fov: query.fov ?? start.fov_y_deg ?? DEFAULT_FOV,
            // the scene camera's fov along its axis (fov_deg, fov_axis: a Mitsuba sensor's), kept at any
            // window size; fov= in the URL is vertical
            along: query.fov === undefined && FOV_AXES.includes(start.fov_axis) && start.fov_deg > 0 && start.fov_deg < 180
                ? { fov: start.fov_deg, axis: start.fov_axis } : null,
        };
        this.renderer = renderer;
        this.renderer.setPixelRatio(1);
        this.renderer.setClearColor(0x000000, 0); // background 0, as the renderer's; render() clears
        this.gl = this.renderer.getContext();
        this.background = null; // the environment where no object is (a version 4 file)
        if (fit.environment) { // its size checked by loadFit
            this.background = backgroundMesh(fit.environment, fit.shaders, this.renderer.extensions.has('OES_texture_float_linear'));
            fit.scene.add(this.background);
        }
        this.reversed = this.renderer.capabilities.reversedDepthBuffer; // reversed Z (EXT_clip_control)
        this.camera = new DepthCamera(this.start.fov, 1, 0.1, 10); // three.js marks it reversedDepth at its first frame

        this.tonemap = new THREE.RawShaderMaterial({
            glslVersion: THREE.GLSL3, vertexShader: fit.shaders.screenVertex, fragmentShader: fit.shaders.tonemapFragment,
            uniforms: { hdr: { value: null }, exposure: { value: this.exposure } }, depthTest: false, depthWrite: false,
        });
        const quad = new THREE.Mesh(fullScreenTriangle(), this.tonemap);
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
        else if (Object.hasOwn(PART_KEYS, k)) {
            const part = PART_KEYS[k];
            if (this.off.has(part)) this.off.delete(part); else this.off.add(part);
        }
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

    // display.renderer.Renderer._matrices: the depth range from the scene's box and the eye
    depthRange() {
        [this.camera.near, this.camera.far] = depthRange(this.fit.bounds, this.camera.position, NEAR_FRACTION[this.reversed]);
    }

    target(width, height) {
        if (!this.hdr || this.hdr.width !== width || this.hdr.height !== height || this.hdr.samples !== this.samples) {
            if (this.hdr) this.hdr.dispose();
            // with reversed Z, float depth: a FloatType depth texture makes three.js's depth
            // buffer DEPTH_COMPONENT32F (multisampled too), never read (resolveDepthBuffer false)
            this.hdr = new THREE.WebGLRenderTarget(width, height, {
                type: THREE.FloatType, format: THREE.RGBAFormat, samples: this.samples > 1 ? this.samples : 0,
                minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter, depthBuffer: true, generateMipmaps: false,
                depthTexture: this.reversed ? new THREE.DepthTexture(width, height, THREE.FloatType) : null,
                resolveDepthBuffer: false,
            });
        }
        return this.hdr;
    }

    draw() {
        const width = Math.max(1, this.canvas.clientWidth);
        const height = Math.max(1, this.canvas.clientHeight);
        if (this.canvas.width !== width || this.canvas.height !== height) this.renderer.setSize(width, height, false);
        this.camera.aspect = width / height;
        if (this.start.along) this.camera.fov = verticalFov(this.start.along.fov, this.start.along.axis, width, height);
        this.depthRange();
        this.camera.updateProjectionMatrix();
        // display.renderer.Renderer.draw and _bind_fitted: the diffuse mode draws the emitted
        // colour alone; a part switched off is not drawn
        const fitted = this.mode === 'fitted';
        for (const mesh of this.fit.objects) {
            const u = mesh.material.uniforms;
            const info = mesh.userData;
            const k = fitted && !this.off.has('lights') ? info.lights : 0;
            u.n_lights.value = this.lights === null ? k : Math.max(0, Math.min(k, this.lights));
            u.n_parts.value = fitted && !this.off.has('emitters') ? info.parts : 0;
            u.probe_size.value = fitted && !this.off.has('probe') ? info.probeSize : 0;
            u.eye.value.copy(this.camera.position);
        }
        if (this.background) this.aimBackground(width, height);
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

    // the background's camera uniforms (display.renderer.Renderer._draw_background): the
    // camera's right, up and forward (radiosity.files.camera.Camera.basis: right =
    // forward x up), tan(fov / 2) times the aspect and 1, the framebuffer's size
    aimBackground(width, height) {
        const u = this.background.material.uniforms;
        this.camera.updateMatrixWorld();
        const back = new THREE.Vector3();
        this.camera.matrixWorld.extractBasis(u.cam_right.value, u.cam_up.value, back);
        u.cam_right.value.normalize();
        u.cam_up.value.normalize();
        u.cam_forward.value.copy(back).normalize().negate();
        const t = Math.tan(THREE.MathUtils.degToRad(this.camera.fov) / 2);
        u.cam_extent.value.set(t * width / height, t);
        u.viewport.value.set(width, height);
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
        const off = this.offParts();
        let text = `${this.mode} | lights ${lights}${off.length ? ` | off: ${off.join(', ')}` : ''} | `
            + `exposure ${this.exposure} | ${this.samples} spp | frame ${mean.toFixed(1)} ms (${(1000 / mean).toFixed(0)} fps)`;
        if (this.showHelp) {
            text += '\nclick: mouse look (Esc frees) | W A S D walk, Q E down/up, Shift faster | M fitted/diffuse | '
                + 'L 2/all lights | 1 2 3 emitters/probe/lights off/on | + - exposure | O orbit/walk | R reset | H hide help';
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

    // the parts switched off, in fitting.model.PARTS's order
    offParts() { return PARTS.filter((p) => this.off.has(p)); }

    state() {
        return {
            mode: this.mode, exposure: this.exposure, lights: this.lights, samples: this.samples, off: this.offParts(),
            frames: this.frames,
            eye: this.camera.position.toArray(), frameMs: [...this.frameMs],
        };
    }
}

export async function main() {
    const overlay = document.getElementById('status');
    const canvas = document.getElementById('view');
    const t0 = performance.now();
    let maxTexture = null;
    try {
        const query = parseQuery(window.location.search);
        // the renderer first: the fit's textures are checked against its GPU's limit before any is made
        // reversed Z where the browser has EXT_clip_control (capabilities.reversedDepthBuffer says)
        const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, alpha: false, preserveDrawingBuffer: true,
                                                   reversedDepthBuffer: true });
        maxTexture = textureLimit(renderer.getContext(), query);
        const fit = await loadFit(query.file, maxTexture, renderer.capabilities.reversedDepthBuffer);
        const walkthrough = new Walkthrough(canvas, overlay, fit, query, renderer);
        window.vlights = {
            walkthrough,
            maxTexture,
            loadMs: performance.now() - t0,
            state: () => walkthrough.state(),
            benchmark: (n) => walkthrough.benchmark(n),
        };
    } catch (err) {
        overlay.textContent = `error: ${err.message}`;
        overlay.classList.add('error');
        document.title = 'error';
        window.vlights = { error: err.message, maxTexture };
        console.error(err);
    }
}
