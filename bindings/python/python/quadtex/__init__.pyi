"""Alias-free texture filtering with incomplete-quadtree textures.

Conventions (as in the Rust crates):

* Texture space is the unit square ``[0, 1)²``, axis ``x`` to the right and
  ``z`` *up*; row 0 of an image is the *top* of the texture.
* Colours are linear light with premultiplied alpha, RGBA.
* A footprint is the texture-space image of one pixel: its four corners, the
  images of the pixel corners (0,0), (1,0), (1,1), (0,1), in that order.

Errors: bad arguments raise ``ValueError`` (shape, value, names; the message
names the offending index, e.g. ``quads[17]: coordinate corner[2].z is not
finite (NaN)``) or ``TypeError`` (an array that does not hold real numbers);
files the operating system refuses raise ``OSError`` (``FileNotFoundError``,
``PermissionError``, ``IsADirectoryError``…, with ``errno`` and ``filename``
set); malformed files raise ``ValueError`` with quadtex's message, which
names the file and the field; work estimated above the memory budget
(``memory_limit``) raises ``ValueError`` naming the estimate and the budget.

Batch calls release the GIL while they filter or integrate, and check for
Ctrl-C every 50 ms or so (``KeyboardInterrupt``).
"""

import os
from typing import Any, Callable, Dict, List, Literal, Optional, Sequence, Tuple, Union, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "Texture",
    "open",
    "pack",
    "pack_tiles",
    "tile_grid",
    "mosaic_tiles",
    "pack_tile",
    "splice_tiles",
    "Scene",
    "Camera",
    "footprints_from_differentials",
    "to_srgb8",
    "save_image",
    "__version__",
]
__version__: str

_StrPath = Union[str, bytes, "os.PathLike[str]", "os.PathLike[bytes]"]
_WrapName = str  # "repeat" | "clamp" | "mirror" | "border"

@final
class Texture:
    """A packed texture: an incomplete quadtree of linear, premultiplied
    RGBA (16 bits a channel). Made by :func:`open` or :func:`pack`."""

    @property
    def depth(self) -> int:
        """Level of the tree's finest squares (side ``2**-depth``)."""

    @property
    def cells(self) -> tuple[int, int]:
        """``(columns, rows)`` of the finest grid over the texture: a packed
        image's own width and height in texels, whatever its size (a texture
        uniform down to its texels included); ``2**depth`` each for square
        vector art."""

    @property
    def node_count(self) -> int:
        """Number of nodes in the tree."""

    @property
    def nbytes(self) -> int:
        """Bytes the tree occupies in memory."""

    @property
    def source_size(self) -> Optional[Tuple[int, int]]:
        """``(width, height)`` of the raster packed (for SVG art the
        effective raster, ``2**level`` on a side), or None if unknown."""

    def filter(
        self,
        quads: npt.ArrayLike,
        wrap: Union[_WrapName, Sequence[_WrapName]] = "repeat",
        weighting: str = "screen",
        border: Sequence[float] = (0.0, 0.0, 0.0, 0.0),
        error_bound: float = 0.001953125,  # 1/512
        level: Optional[int] = None,
        budget: Optional[int] = None,
        return_bound: bool = False,
        threads: Optional[int] = None,
    ) -> Union[
        npt.NDArray[np.float32],
        Tuple[npt.NDArray[np.float32], npt.NDArray[np.float64]],
    ]:
        """Mean colour over each footprint.

        quads: ``(N, 4, 2)`` texture-space corners in pixel order (any real
            dtype, converted to float64; any strides).
        wrap: how texture space continues beyond the unit square, one name
            for both axes or a pair ``(x, z)``: ``"repeat"``, ``"clamp"``,
            ``"mirror"`` or ``"border"``.
        weighting: ``"screen"`` (a box over the pixel: texture area weighted
            by the screen area that sees it, from the projective map the
            corners fix) or ``"texture"`` (a box over the footprint in
            texture space). They agree for parallelograms.
        border: linear premultiplied RGBA shown outside the unit square on
            an axis whose wrap is ``"border"``.
        error_bound: ``> 0``; the bound each footprint's error aims at,
            relative to the texture's contrast: squares are refined,
            largest error first, until it is met (whatever the footprint's
            size), or ``budget`` squares are spent if a budget is given.
        level: if given (0..30), every square is refined down to this
            level (clamped to the tree's depth) instead; ``error_bound`` is
            then unused (still checked).
        budget: ``None`` (the default: no budget, refine until the bound is
            met) or ``>= 1``, the most squares refined per footprint under
            ``error_bound``; a footprint it stops reports a bound above
            ``error_bound``.
        return_bound: also return each footprint's error bound reached.
        threads: ``None`` (every core) or ``>= 1`` (1: the calling thread
            only, for callers that run batches on threads of their own);
            the results are bit-identical whatever the count.

        Returns ``(N, 4)`` float32 linear premultiplied RGBA; with
        ``return_bound=True`` the pair ``(rgba, bound)``, ``bound`` an
        ``(N,)`` float64 array: every channel of footprint i is within
        ``bound[i]`` times the texture's contrast of the exact mean.

        Raises ValueError for a NaN, infinite or too large coordinate
        (beyond 1e15) or a quad that crosses itself (a bow tie), naming it.

        Raises ``KeyboardInterrupt`` on Ctrl-C (checked every 50 ms or so).
        """

    def integrate(
        self,
        rects: npt.ArrayLike,
        level: Optional[int] = None,
        threads: Optional[int] = None,
    ) -> npt.NDArray[np.float64]:
        """Integral of colour over each rectangle's overlap with the unit
        square, no wrap: what ``quadtex query`` prints.

        rects: ``(N, 4)`` rows ``x0 z0 x1 z1`` with ``x0 <= x1``, ``z0 <= z1``.
        level: traverse down to this level (0..30; default the tree's depth).
        threads: ``None`` (every core) or ``>= 1``, as for :meth:`filter`.

        Returns ``(N, 4)`` float64 linear premultiplied RGBA × area; divide
        by the rectangle's area for its mean colour.
        """

    def save(self, path: _StrPath) -> None:
        """Writes a ``.qtx`` file atomically (a temporary file in the same
        directory, renamed over ``path``). A symbolic link is followed (the
        file it names is replaced; the link stays); a device or FIFO is
        written in place. A directory raises ``IsADirectoryError`` (errno
        ``EISDIR``, ``filename`` set)."""

    def verify(self) -> None:
        """Checks every colour and texel of the tree: what
        ``open(path, mapped=True)`` leaves unread. Raises ``ValueError``
        naming the file and the first node that fails."""

    def __repr__(self) -> str: ...

def open(path: _StrPath, mapped: bool = False, verify: bool = True) -> Texture:
    """Reads a ``.qtx`` file, checking its checksums and every colour.

    mapped: if True the file is memory-mapped instead: its header, structure
        and payload checksum are checked (one pass at memory speed, so a
        damaged file is refused) and queries read the nodes they touch;
        :meth:`Texture.verify` checks the colours' invariants.
    verify: with ``mapped=True`` only: False skips the payload checksum for
        trusted files, giving up the promise that a damaged file is refused.
    """

def pack(
    source: Union[_StrPath, npt.ArrayLike],
    tolerance: float = 0.0,
    max_level: Optional[int] = None,
    hdr: bool = False,
    contour_leaves: Optional[int] = None,
    max_sweep_work: Optional[int] = None,
    memory_limit: Optional[int] = None,
    resources: Optional[Literal["same-folder", "anywhere", "none"]] = None,
) -> Texture:
    """Packs an image into a texture, as ``quadtex pack`` does.

    source: a path to a PNG, JPEG, OpenEXR or Radiance ``.hdr`` image or an
        SVG document (OpenEXR and ``.hdr`` files pack as HDR textures: half
        floats, unclamped), or an array ``(H, W)`` or ``(H, W, C)`` with
        C = 1 (grey), 2 (grey, alpha), 3 (RGB) or 4 (RGBA), row 0 at the top:

        * ``uint8`` / ``uint16``: sRGB-encoded, straight alpha, exactly as an
          8- / 16-bit PNG is decoded (sRGB → linear, then premultiplied);
          8-bit texels are kept as they are in the tree's texel blocks;
        * floating point: linear light, *premultiplied* alpha. With
          ``hdr=True`` kept unclamped as half floats (alpha clamped to
          [0, 1]), as an OpenEXR file is read; otherwise clamped (alpha to
          [0, 1], colour to [0, alpha]; without alpha, colour to [0, 1]).
          NaN or infinity is a ValueError.

    tolerance: in [0, 1]; largest per-channel deviation (linear,
        premultiplied) of a texel from its leaf's colour. 0 is lossless.
        Raster images only (SVG art packs exactly; its gradients to a
        quarter of an 8-bit step).
    max_level: depth of the tree's finest cells (0..30; a raster builds at
        most 15). Default: the smallest level whose cells are no larger than
        a texel for rasters; for SVG 12 (20 with ``contour_leaves``),
        lowered (not below 8) when the packing's estimate is above
        ``memory_limit``, as ``quadtex pack`` does (``source_size`` is
        ``2**level``). A level given is kept: SVG art that does not fit at
        it is a ``ValueError``.
    hdr: float arrays only: keep them unclamped as half floats (as an
        OpenEXR file is read) instead of clamping them. Files decide by
        their format (OpenEXR and ``.hdr`` are HDR).
    contour_leaves: SVG art only, 3..1024: squares of flat art crossed by
        at most this many edges keep their contours (``quadtex pack
        --contour-leaves``), exact at any magnification; the texture then
        answers down to level 30. Default: off.
    max_sweep_work: SVG art only, at least 1: the most steps the exact
        coverage sweep may take (``quadtex pack --max-sweep-work``); art
        needing more (thousands of dashes piled on a point) is a ValueError
        naming the steps it needs. Default: 2**31, about a minute.
    memory_limit: bytes (at least 1), the memory decoding and packing may
        use (``quadtex pack --memory-limit``): work estimated above it is
        refused with a ``ValueError`` naming the estimate and the budget,
        before it allocates. Default: the detected budget (the smallest of
        the cgroup's limit, the address space left and 3/4 of physical
        memory), as the CLI's.
    resources: SVG art only: which files its ``<image href>`` may read
        (``quadtex pack --resources``): ``"same-folder"`` (default: only
        files inside the SVG's own folder; no absolute path, no ``..`` or
        symbolic link out of it), ``"anywhere"`` (any readable file; for
        trusted files) or ``"none"`` (data: URIs only, which are always
        read). A refused reference is a ValueError naming the SVG and the
        reference.

    A folder of tiles packs with :func:`pack_tiles`.
    """

def pack_tiles(
    directory: _StrPath, tolerance: float = 0.0, memory_limit: Optional[int] = None
) -> Texture:
    """Packs a folder of raster tiles, or a tiled TIFF, into one texture,
    one tile in memory at a time, as ``quadtex pack-tiles`` does: the
    texture :func:`pack` would make of the whole mosaic.

    directory: a folder of tiles named ``ROW_COL.png`` (or ``.jpg``; row 0
        at the top): a complete grid of 1, 2, 4, … tiles a side, every tile
        the same power-of-two square; or a tiled TIFF (BigTIFF and
        Cloud-Optimized GeoTIFF included) of any size whose tiles are
        power-of-two squares, partial edge tiles included.
    tolerance: in [0, 1], as for :func:`pack` (0 is lossless).
    memory_limit: bytes, as for :func:`pack`.
    """

def tile_grid(directory: _StrPath) -> tuple[int, int]:
    """``(tiles, side)`` of a folder of tiles or a tiled TIFF as
    :func:`pack_tiles` reads it: tiles on a side of the tree's square and
    texels on a tile's side. A TIFF that is not a square of whole tiles
    covers the square's bottom-left part; :func:`mosaic_tiles` lists the
    tiles that hold texture."""

def mosaic_tiles(directory: _StrPath) -> list[tuple[int, int]]:
    """The tiles :func:`splice_tiles` asks for, ``(row, col)`` (row 0 at the
    top of the tree's square), in its order (Morton, from the bottom-left):
    every tile of a folder; of a tiled TIFF, those holding part of the
    image (the others are pad, never packed)."""

def pack_tile(
    directory: _StrPath,
    row: int,
    col: int,
    tolerance: float = 0.0,
    memory_limit: Optional[int] = None,
    block_format: Optional[int] = None,
) -> bytes:
    """Packs tile ``(row, col)`` (row 0 at the top; one of
    :func:`mosaic_tiles`) of a tile folder or tiled TIFF on its own, for
    :func:`splice_tiles`; returns it as bytes (checked when read
    back). ``block_format``: None (the tile's own), or the code
    :func:`splice_tiles` passes when it asks for the tile again in a wider
    format."""

def splice_tiles(
    directory: _StrPath,
    load: Callable[[int, int, Optional[int]], bytes],
    tolerance: float = 0.0,
    memory_limit: Optional[int] = None,
) -> Texture:
    """Splices tiles packed by :func:`pack_tile` into the texture
    :func:`pack_tiles` makes of the folder, byte for byte. ``load(row, col,
    block_format)`` returns ``pack_tile(directory, row, col, tolerance,
    block_format=block_format)``; tiles are asked for in Morton order, again
    with a ``block_format`` code when the tiles before need a wider one."""

@final
class Camera:
    """One frame's camera along a camera path: the pose the path's spline
    gives at the frame's time (world space, ``y`` up). Made by
    :meth:`Scene.path_frames`."""

    @property
    def frame(self) -> int:
        """The frame's index along the path (0 for the first)."""

    @property
    def time(self) -> float:
        """The frame's time on the path's clock (the keys' ``time`` unit)."""

    @property
    def position(self) -> Tuple[float, float, float]:
        """Where the camera is."""

    @property
    def look_at(self) -> Tuple[float, float, float]:
        """The point it looks at."""

    @property
    def up(self) -> Tuple[float, float, float]:
        """The up direction fixing the roll, as interpolated (not made
        perpendicular to the view)."""

    @property
    def fov(self) -> float:
        """Vertical field of view, degrees."""

    def __repr__(self) -> str: ...

@final
class Scene:
    """A scene as ``quadtex render`` reads it (``docs/scenes.md``): planes,
    quads, spheres, OBJ and glTF models, textures packed once, sky and
    lights. Made by :meth:`Scene.open`; :meth:`Scene.render` renders it."""

    @staticmethod
    def open(
        path: _StrPath,
        memory_limit: Optional[int] = None,
        resources: Optional[Literal["same-folder", "anywhere", "none"]] = None,
    ) -> "Scene":
        """Reads a TOML scene file, as ``quadtex render SCENE`` does: its
        models and textures (``.qtx``, PNG, JPEG, OpenEXR, ``.hdr``, SVG,
        ``builtin:``) are read and packed now, once. ``.qtx`` textures are
        read whole and checked, as the CLI reads them.

        memory_limit: bytes (at least 1), the memory reading and packing
            textures may use (``--memory-limit``); default the detected
            budget.
        resources: which files glTF models and SVG textures may read
            (``--resources``); default ``"same-folder"``.

        Raises ``OSError`` when the system refuses the scene file
        (``FileNotFoundError``…, ``errno`` and ``filename`` set) and
        ``ValueError`` for a malformed scene, naming the file, line and key
        (``shape[0].texture``); a texture that cannot be read is a
        ``ValueError`` naming its key, with the system's message. The GIL
        is released while reading.
        """

    @property
    def width(self) -> int:
        """The camera's width in pixels (the default render width)."""

    @property
    def height(self) -> int:
        """The camera's height in pixels (the default render height)."""

    def render(
        self,
        width: Optional[int] = None,
        height: Optional[int] = None,
        filter: str = "quadtree",
        pixel_filter: Literal["box", "tent", "mitchell"] = "box",
        path: Optional[_StrPath] = None,
        frame: Optional[int] = None,
        frames: Optional[int] = None,
        error_bound: Optional[float] = None,
        budget: Optional[int] = None,
        level: Optional[int] = None,
        quality: float = 1.0,
        progress: bool = False,
        return_summary: bool = False,
    ) -> Union[
        npt.NDArray[np.float32], Tuple[npt.NDArray[np.float32], Dict[str, Any]]
    ]:
        """Renders the scene as ``quadtex render`` does: the same pixels as
        its OpenEXR output (``--format exr``), bit for bit.

        width, height: pixels (at least 1; at most 2**26 pixels in all).
            Default the camera's; one alone keeps the camera's aspect.
        filter: the texture filter (``--filter``): ``"quadtree"`` (the
            method), ``"nearest"``, ``"bilinear"``, ``"supersample:N"`` (N×N
            nearest rays a pixel, N in 1..64), ``"trilinear"``, ``"ewa"``
            (anisotropy 8) or ``"sat"``.
        pixel_filter: ``"box"``, ``"tent"`` or ``"mitchell"``
            (``--pixel-filter``), for quadtree and supersample.
        path: a camera path file (``--path``; TOML keys, ``docs/scenes.md``)
            to take the camera from instead of the scene's; needs ``frame``
            and ``frames``. Frame ``frame`` of ``frames`` is exactly the
            file ``quadtex render SCENE --path PATH --frames FRAMES``
            writes as ``frame_<frame>.exr``.
        frame: with ``path``: which frame, ``0 <= frame < frames``.
        frames: with ``path``: frames along it, 1..100000 (``--frames``).
        error_bound: quadtree only: ``> 0`` (default 1/512), the bound each
            pixel aims at (``--error-bound``).
        budget: quadtree only: ``>= 1`` (default 64), most squares a pixel
            region refines (``--budget``).
        level: quadtree only: 0..30, refine every square to this level
            instead (``--level``).
        quality: sat only, in [1, 64] (``--quality``).
        progress: print ``quadtex: rendered R/H rows (P%)`` to standard
            error (file descriptor 2, not ``sys.stderr``) as each tenth of
            the rows is done.
        return_summary: also return what the render cost: a dict with
            ``width``, ``height``, ``seconds``, ``textured_pixels``,
            ``max_error_bound``, ``mean_error_bound``, ``over_target``,
            ``max_weight_error`` and ``text`` (the CLI's summary line).

        Returns ``(height, width, 4)`` float32, linear light, premultiplied
        RGBA, row 0 at the top (:func:`to_srgb8` and :func:`save_image`
        make PNG bytes and files of it); with ``return_summary=True`` the
        pair ``(image, summary)``.

        Raises ``ValueError`` naming the argument (an unknown filter, a zero
        size, ``frame >= frames``, ``frame`` without ``path``…), a malformed
        camera path (file, line and key) or a frame whose camera is
        degenerate; ``OSError`` when the system refuses the path file. The
        GIL is released while rendering, on every core; Ctrl-C is seen when
        the frame is done.
        """

    def path_frames(self, path: _StrPath, frames: int) -> List[Camera]:
        """The camera of each frame along a camera path, as ``quadtex render
        --path PATH --frames FRAMES`` places them: frame i of N is the
        path's pose at time ``t0 + (t_last - t0)·i/(N - 1)`` (the first key
        when N = 1); ``position`` and ``look_at`` follow a Catmull–Rom
        spline through the keys, ``up`` and ``fov`` are linear between them.

        path: a camera path file (TOML keys, ``docs/scenes.md``).
        frames: how many frames along it, 1..100000.

        Returns ``frames`` :class:`Camera` objects in frame order. Raises
        ``ValueError`` for a malformed path (file, line and key), ``frames``
        out of range, or a degenerate frame (named, as the CLI checks every
        frame before rendering); ``OSError`` when the system refuses the file.
        """

    def __repr__(self) -> str: ...

def footprints_from_differentials(
    points: npt.ArrayLike, dpdx: npt.ArrayLike, dpdy: npt.ArrayLike
) -> npt.NDArray[np.float64]:
    """The footprints a renderer's ray differentials give: parallelograms
    whose corner ``(i, j)`` is ``points + (i - 1/2)·dpdx + (j - 1/2)·dpdy``
    (Rust ``Footprint::from_differentials``), in pixel order
    ``(0,0), (1,0), (1,1), (0,1)``: ready for :meth:`Texture.filter`.

    points: ``(N, 2)``, the texture point ``(x, z)`` at each pixel centre.
    dpdx: ``(N, 2)``, its change per pixel step to the right.
    dpdy: ``(N, 2)``, its change per pixel step *down* the screen.

    Returns ``(N, 4, 2)`` float64. Raises ``ValueError`` for another shape,
    differing lengths, a value that is not finite (named, e.g.
    ``dpdx[3, 1]``) or a corner beyond 1e15 (naming the row); ``TypeError``
    for arrays that do not hold real numbers.
    """

def to_srgb8(image: npt.ArrayLike) -> npt.NDArray[np.uint8]:
    """8-bit sRGB with straight alpha: the bytes ``quadtex render -o x.png``
    stores for a rendered image (the same code).

    image: ``(H, W, 4)`` floating point (float64 is rounded to float32
        first), linear light, premultiplied: what :meth:`Scene.render`
        returns.

    Returns ``(H, W, 4)`` uint8: colour divided by alpha (0 where alpha is
    not above 0), sRGB-encoded and rounded (NaN and below 0 give 0, above 1
    give 255); alpha ``round(255·clip(a, 0, 1))``. Raises ``ValueError``
    (shape, empty) or ``TypeError`` (not floating point).
    """

def save_image(path: _StrPath, image: npt.ArrayLike) -> None:
    """Writes a rendered image atomically, as ``quadtex render -o`` does;
    the format follows the extension: ``.png`` (8-bit sRGB, straight alpha:
    the bytes of :func:`to_srgb8`) or ``.exr`` (32-bit float, linear,
    premultiplied).

    path: ending in ``.png`` or ``.exr`` (any case); another extension is a
        ``ValueError``.
    image: ``(H, W, 4)`` floating point, linear premultiplied RGBA.

    Raises ``OSError`` when the system refuses (``IsADirectoryError``,
    ``FileNotFoundError``…, ``errno`` and ``filename`` set), ``ValueError``
    or ``TypeError`` for a bad image.
    """
