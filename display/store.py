"""The renderer's float store: every object's per-vertex float data the shaders read by
index, in a few 2D array textures (``display/shaders/store.glsl`` reads it).

What it holds, one RGB32F value a texel: the solution's radiance grids (the reference
display: (V, D, 3) an object), the fitted per-light coefficients ((V, K, 3)) and the
emitters' visibility ((V, P), in red). Each object's block starts at a value ``offset``
(``StorePlan.add``); the shaders get its address (layer, texel) = divmod(offset, L)
and find a vertex's row of it in 32-bit unsigned arithmetic that stays exact whatever
the offset (store.glsl's ``store_start``): a flat texel index passes 2^31 at 2.1e9
values and a float index 3 i at 7.2e8.

Layout (``StoreLayout``): ``layers`` layers of WIDTH x ``rows`` texels, value i at
layer i // L, texel t = i % L, (x, y) = (t % WIDTH, t // WIDTH), L = WIDTH * rows texels
a layer; the layers ``page_layers`` to a texture (a "page", each a sampler of its own,
MAX_PAGES at most). WIDTH and rows are powers of two, rows at least 16, so L is a power
of two of at least 2^16 and the shaders divide by shifts alone (a division by a uniform
is scalarised on llvmpipe: it made the per-pixel reference display half as slow again).
A store of up to LARGE_ROWS rows is one layer of the least such rows; a larger one is
layers of LARGE_ROWS rows (12.6 MB each: the padding is under one), as many as it needs.

Why not one texture: a 2D texture has at most GL_MAX_TEXTURE_SIZE rows (16384 on
llvmpipe: 67 million values 4096 wide, fewer than the 79 million a user's solution
had), and llvmpipe makes no texture of 2 GiB or more, counting 16 bytes an RGB32F texel
(measured: an array of 4096 x 16376 x 2 is made, 4096 x 16384 x 2 and 4096 x 8192 x 4
are not; it stores 12), so one array texture holds fewer than 2^27 values (1.6 GB of
float32): 127 layers of 2^20; MAX_PAGES of them hold 1.07e9 values, 12.8 GB, more than
a 24 GB machine holds twice (the host copy and the textures). Why arrays and not
GL_TEXTURE_BUFFER: moderngl (5.13) makes no buffer textures, and their limit
(GL_MAX_TEXTURE_BUFFER_SIZE, 2^27 texels on llvmpipe) is no larger than an array's.

The values are streamed into the textures a band of rows at a time (``Store.fill``),
from each block's chunks, never gathered into one host array. ``check_memory`` refuses,
in one line, textures and buffers that would not fit in the memory left, and says the
estimate of an upload of SAY_BYTES or more before it is made.
"""

from __future__ import annotations

from typing import NamedTuple

import moderngl
import numpy as np

from radiosity.files.errors import InputError
from radiosity.policies.limits import available_memory

from .gl import MAX_BUFFER_BYTES, _size
from .glsl import FLOAT_TEXTURE_WIDTH

WIDTH = FLOAT_TEXTURE_WIDTH      # texels a row (store.glsl's VL_TEXTURE_WIDTH): a power of two
MIN_ROWS = 16                    # rows a layer at least: L >= 2^16 (store.glsl's store_start)
LARGE_ROWS = 256                 # rows a layer of a store of several layers: 2^20 values
MAX_STRIDE = 1 << 16             # the longest row of a block store_start addresses (a 256 x 256 grid)
MAX_PAGES = 8                    # the if-chain of store.glsl's store_fetch
FIRST_UNIT = 8                   # pages at texture units 8 .. 8 + pages - 1 (the renderer's others: 0 .. 7)
TEXEL_BYTES = 12                 # an RGB32F texel as stored
COUNTED_TEXEL_BYTES = 16         # as llvmpipe counts it against MAX_BUFFER_BYTES
BAND_ROWS = 256                  # rows written at once, at most
STAGING_BYTES = BAND_ROWS * WIDTH * TEXEL_BYTES  # the host's band of rows while filling (12.6 MB)
# Limits below the context's, for tests: rows a layer, layers a page (None: the context's)
LAYER_ROWS = None
PAGE_LAYERS = None


class StoreLayout(NamedTuple):
    """``layers`` layers of WIDTH x ``rows`` texels, ``page_layers`` a texture, for
    ``values`` values (the rest padding)."""

    values: int
    rows: int
    layers: int
    page_layers: int

    @property
    def layer_texels(self):
        return WIDTH * self.rows

    @property
    def shift(self):
        """log2 of ``layer_texels`` (store.glsl's store_shift)."""
        return self.layer_texels.bit_length() - 1

    @property
    def pages(self):
        return _ceil_div(self.layers, self.page_layers)

    def page_depth(self, page):
        """The layers of texture ``page`` (the last may have fewer)."""
        return min(self.page_layers, self.layers - page * self.page_layers)

    @property
    def nbytes(self):
        return self.layers * self.layer_texels * TEXEL_BYTES

    def address(self, index):
        """(layer, texel within the layer) of value ``index``: what the shaders get as a
        block's base (ints of any size in, each below 2^31 out)."""
        return divmod(int(index), self.layer_texels)

    def texel(self, index):
        """(page, x, y, layer within the page) of value ``index``: what store.glsl's
        ``store_fetch`` reads."""
        layer, t = self.address(index)
        page, z = divmod(layer, self.page_layers)
        return page, t % WIDTH, t // WIDTH, z


def _ceil_div(a, b):
    return -(-a // b)


def context_limits(ctx):
    """(rows a layer, layers a page, pages) at most for ``ctx``: its largest texture and
    array; the pages the texture units of a stage leave (FIRST_UNIT taken)."""
    info = ctx.info
    units = min(int(info.get(name) or 16) for name in ("GL_MAX_TEXTURE_IMAGE_UNITS", "GL_MAX_VERTEX_TEXTURE_IMAGE_UNITS"))
    rows = int(info.get("GL_MAX_TEXTURE_SIZE") or 1024)
    layers = int(info.get("GL_MAX_ARRAY_TEXTURE_LAYERS") or 256)
    if LAYER_ROWS is not None:
        rows = min(rows, LAYER_ROWS)
    if PAGE_LAYERS is not None:
        layers = min(layers, PAGE_LAYERS)
    return rows, layers, max(0, min(MAX_PAGES, units - FIRST_UNIT))


def _floor_power_of_two(n):
    return 1 << (max(int(n), 1).bit_length() - 1)


def store_layout(values, max_rows, max_layers, max_pages=MAX_PAGES, what="the model"):
    """The layout of ``values`` values in layers of at most ``max_rows`` rows (and
    LARGE_ROWS when there are several), textures of at most ``max_layers`` layers and
    under MAX_BUFFER_BYTES (as llvmpipe counts them), at most ``max_pages`` textures;
    InputError naming ``what`` beyond them."""
    values = max(int(values), 1)
    page_texels = (MAX_BUFFER_BYTES - 1) // COUNTED_TEXEL_BYTES
    cap = _floor_power_of_two(min(int(max_rows), LARGE_ROWS, page_texels // WIDTH))
    if cap < MIN_ROWS:
        raise InputError(f"this OpenGL's textures hold fewer than {MIN_ROWS} rows of {WIDTH} texels")
    needed = _ceil_div(values, WIDTH)  # rows
    if needed <= cap:  # one layer of the least power of two of rows
        rows, layers = max(MIN_ROWS, 1 << (needed - 1).bit_length()), 1
    else:
        rows, layers = cap, _ceil_div(needed, cap)
    page_layers = max(1, min(int(max_layers), page_texels // (WIDTH * rows)))
    layout = StoreLayout(values, rows, layers, page_layers)
    if layout.pages > max_pages:
        most = max_pages * page_layers * WIDTH * rows
        raise InputError(
            f"{what} has {values:,} RGB values for the display to read, in {layout.pages} textures of at most "
            f"{page_layers * WIDTH * rows:,}; this OpenGL binds {max_pages} for them ({most:,} values); "
            "use a coarser --grid or --max-edge"
        )
    return layout


class Estimate(NamedTuple):
    """Bytes a renderer adds to memory: the store's textures, the vertex buffers and the
    other textures, the host's staging while uploading; ``host`` the arrays already read."""

    store: int
    buffers: int
    staging: int
    host: int

    @property
    def total(self):
        return self.store + self.buffers + self.staging


SAY_BYTES = 1 << 30  # an upload this large is said before it is made (it takes seconds)


def _parts(estimate, layout):
    textures = f"{layout.pages} texture{'s' if layout.pages > 1 else ''}"
    return (f"its {layout.values:,} RGB values in {textures} ({_size(estimate.store)}), vertex buffers "
            f"({_size(estimate.buffers)}) and upload staging ({_size(estimate.staging)}), next to the "
            f"{_size(estimate.host)} host copy already read")


def check_memory(estimate, layout, free=None, say=None):
    """Refuse (InputError, one line) an ``estimate`` (``Estimate``) beyond the memory this
    process may still use (``radiosity.policies.limits.available_memory``, or ``free``);
    ``say`` (a function of one line), if given, is told an estimate of SAY_BYTES or more
    first."""
    free = available_memory() if free is None else free
    if say is not None and estimate.total >= SAY_BYTES:
        have = "" if free is None else f" ({_size(free)} free)"
        say(f"drawing: about {_size(estimate.total)} more memory{have}: {_parts(estimate, layout)}")
    if free is not None and estimate.total > free:
        raise InputError(
            f"drawing this model needs about {_size(estimate.total)} more memory: {_parts(estimate, layout)}; "
            f"only {_size(free)} is free. Use a coarser --grid or --max-edge, or a machine with more memory"
        )


class StorePlan:
    """The blocks of the store, in order: ``add(count, chunks)`` gives each its offset;
    ``chunks()`` yields its values, (..., 3) or (n,) (red alone) float arrays, ``count``
    values in all, made when the store is filled (so a block need never be whole in memory)."""

    def __init__(self):
        self.blocks = []
        self.values = 0

    def add(self, count, chunks):
        offset = self.values
        self.blocks.append((int(count), chunks))
        self.values += int(count)
        return offset


class Store:
    """The pages of ``layout`` (RGB32F array textures), filled from ``plan``."""

    def __init__(self, ctx, layout, plan):
        if max(plan.values, 1) != layout.values:
            raise ValueError(f"a plan of {plan.values} values in a layout of {layout.values}")
        self.layout = layout
        rows = layout.rows
        self.pages = [ctx.texture_array((WIDTH, rows, layout.page_depth(p)), 3, None, dtype="f4")
                      for p in range(layout.pages)]
        for page in self.pages:
            page.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.fill(plan)

    def fill(self, plan):
        """Stream the plan's blocks into the pages, a band of rows at a time, zeros after
        the last value of the last band."""
        band = min(self.layout.rows, BAND_ROWS)  # powers of two: a band divides a layer
        staging = np.zeros((band * WIDTH, 3), np.float32)
        cap, filled, written = len(staging), 0, 0
        for count, chunks in plan.blocks:
            given = 0
            for values in chunks():
                flat = np.asarray(values, np.float32)
                flat = flat if flat.ndim == 1 else flat.reshape(-1, 3)
                given += len(flat)
                pos = 0
                while pos < len(flat):
                    take = min(len(flat) - pos, cap - filled)
                    if flat.ndim == 1:
                        staging[filled:filled + take, 0] = flat[pos:pos + take]
                        staging[filled:filled + take, 1:] = 0.0
                    else:
                        staging[filled:filled + take] = flat[pos:pos + take]
                    filled += take
                    pos += take
                    if filled == cap:
                        self._write(staging, written, band)
                        written += cap
                        filled = 0
            if given != count:
                raise ValueError(f"a block of the store gave {given} values, not {count}")
        if filled:
            staging[filled:] = 0.0
            self._write(staging, written, band)

    def _write(self, staging, index, band):
        page, _, y, z = self.layout.texel(index)
        self.pages[page].write(staging, viewport=(0, y, z, WIDTH, band, 1))

    def bind(self, program):
        """Bind the pages to their units and set ``program``'s store uniforms (store.glsl)."""
        units = [FIRST_UNIT + p for p in range(len(self.pages))]
        for unit, page in zip(units, self.pages):
            page.use(location=unit)
        if "store" in program:
            program["store"].value = units if len(units) > 1 else units[0]
        for name, value in (("store_shift", self.layout.shift), ("store_layers", self.layout.page_layers)):
            if name in program:
                program[name].value = value

    @property
    def define(self):
        """The ``#define`` (a ``display.glsl.stage`` extra) of the programs reading it."""
        return f"VL_STORE_PAGES {len(self.pages)}"

    @property
    def nbytes(self):
        return self.layout.nbytes

    def release(self):
        for page in self.pages:
            page.release()
        self.pages = []
