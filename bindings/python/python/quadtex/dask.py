"""quadtex on a Dask cluster (``dask.distributed``): a camera path's frames,
batches of footprints and the tiles of a mosaic as tasks.

Needs the optional extra: ``pip install ./bindings/python[dask]``. The same
code runs on a laptop (``distributed.LocalCluster``), on HPC schedulers
(dask-jobqueue) and on Kubernetes; ``docs/dask.md`` has the measurements and
how to size workers.

Files are shared, not shipped: every worker must see the scene, camera path,
texture or tile folder at the same path (a shared file system or object
store mount), and ``render_path`` writes frames where the client asked.
Workers open what they read once and keep it open (textures memory-mapped)
across their tasks.

- :func:`render_path` renders frames of a camera path as tasks, each written
  atomically under the CLI's name; the files equal ``quadtex render SCENE
  --path P --frames N`` byte for byte. A frame whose file exists is
  complete and skipped, so a rerun resumes, and a task retried after its
  worker died never leaves a half-written frame.
- :func:`filter` maps a dask array of footprints ``(N, 4, 2)`` to colours
  ``(N, 4)``, equal to :meth:`quadtex.Texture.filter` on the whole array.
- :func:`pack_tiles` packs a tile folder's tiles on the workers and splices
  them on the client into the ``.qtx`` file ``quadtex pack-tiles`` writes,
  byte for byte; workers send packed subtrees, not texels.
"""

from __future__ import annotations

import os
import threading
import uuid
from typing import TYPE_CHECKING, Any, Dict, List, Optional, Tuple, Union

import numpy as np

import quadtex

if TYPE_CHECKING:  # pragma: no cover
    import dask.array
    import distributed

__all__ = ["render_path", "filter", "pack_tiles"]

_PathLike = Union[str, "os.PathLike[str]"]

# What a worker process keeps open across its tasks, keyed by path and the
# file's identity (so an edited file is opened again).
_OPEN: Dict[Tuple[str, str, int, int], Any] = {}
_OPEN_LOCK = threading.Lock()


def _identity(path: str) -> Tuple[int, int]:
    st = os.stat(path)
    return (st.st_mtime_ns, st.st_size)


def _cached(kind: str, path: str, opener: Any) -> Any:
    key = (kind, path, *_identity(path))
    with _OPEN_LOCK:
        found = _OPEN.get(key)
        if found is None:
            found = opener(path)
            _OPEN[key] = found
        return found


def _texture(path: str) -> "quadtex.Texture":
    return _cached("texture", path, lambda p: quadtex.open(p, mapped=True))


def _scene(path: str) -> Any:
    return _cached("scene", path, quadtex.Scene.open)


def _frame_name(frame: int, frames: int, extension: str) -> str:
    """The CLI's name of frame ``frame`` of ``frames``: ``frame_0007.png``,
    at least four digits, more for longer paths."""
    digits = max(4, len(str(max(frames - 1, 1))))
    return f"frame_{frame:0{digits}d}.{extension}"


def _render_frame(
    scene_path: str,
    path_path: str,
    frame: int,
    frames: int,
    file: str,
    options: Dict[str, Any],
) -> str:
    """Renders one frame on a worker and renames it into place; skips a frame
    whose file is already there (complete: files are renamed whole)."""
    if os.path.isfile(file):
        return file
    scene = _scene(scene_path)
    image = scene.render(path=path_path, frame=frame, frames=frames, **options)
    quadtex.save_image(file, image)
    return file


def render_path(
    client: "distributed.Client",
    scene_path: _PathLike,
    path_path: _PathLike,
    frames: int,
    out_dir: _PathLike,
    width: Optional[int] = None,
    height: Optional[int] = None,
    filter: str = "quadtree",
    pixel_filter: str = "box",
    format: str = "png",
    frame_range: Optional[Tuple[int, int]] = None,
    progress: bool = False,
) -> List[str]:
    """Renders frames of a camera path on the cluster, one task a frame.

    Parameters:
      client: a ``distributed.Client``.
      scene_path: the scene (as ``quadtex render`` reads: TOML, glTF, OBJ).
      path_path: the camera path (``*.path.toml``).
      frames: frames along the path, >= 1 (``--frames``).
      out_dir: the folder the frames go to (made if missing), as
        ``frame_0000.png``, ``frame_0001.png``, … like the CLI.
      width, height: image size; None: the scene's (``--width``, ``--height``).
      filter, pixel_filter: as ``quadtex render --filter``, ``--pixel-filter``.
      format: ``"png"`` (8-bit sRGB) or ``"exr"`` (linear float).
      frame_range: ``(first, last)`` inclusive, or None for all
        (``--range``).
      progress: show Dask's progress bar while waiting.

    Returns: the frames' file names, in order. A frame whose file exists is
    skipped (resume); a task retried after its worker died renames a whole
    frame into place or none.

    Raises: ValueError for bad arguments (before any task runs); whatever a
    frame's task raised (the first one, after the others are cancelled).
    """
    if not isinstance(frames, int) or frames < 1:
        raise ValueError(f"frames must be an integer >= 1, got {frames!r}")
    if format not in ("png", "exr"):
        raise ValueError(f'format must be "png" or "exr", got {format!r}')
    first, last = (0, frames - 1) if frame_range is None else frame_range
    if not (0 <= first <= last < frames):
        raise ValueError(f"frame_range must be (first, last) with 0 <= first <= last < {frames}, got {frame_range!r}")
    scene_path, path_path = os.fspath(scene_path), os.fspath(path_path)
    for name, p in (("scene_path", scene_path), ("path_path", path_path)):
        if not os.path.isfile(p):
            raise FileNotFoundError(2, f"{name}: no such file", p)
    out_dir = os.path.abspath(os.fspath(out_dir))
    os.makedirs(out_dir, exist_ok=True)
    options: Dict[str, Any] = {"filter": filter, "pixel_filter": pixel_filter}
    if width is not None:
        options["width"] = width
    if height is not None:
        options["height"] = height
    # Check the arguments once on the client (a bad filter name fails here,
    # not on every worker): the path's cameras, and one tiny render.
    scene = quadtex.Scene.open(scene_path)
    scene.path_frames(path_path, frames)
    files = [os.path.join(out_dir, _frame_name(i, frames, format)) for i in range(first, last + 1)]
    token = uuid.uuid4().hex[:8]
    futures = [
        client.submit(
            _render_frame,
            scene_path,
            path_path,
            i,
            frames,
            file,
            options,
            key=f"quadtex-frame-{i}-{token}",
            retries=2,
        )
        for i, file in zip(range(first, last + 1), files)
    ]
    if progress:
        from distributed import progress as show

        show(futures)
    return list(client.gather(futures))


def _filter_block(quads: np.ndarray, texture_path: str, options: Dict[str, Any]) -> np.ndarray:
    texture = _texture(texture_path)
    return np.asarray(texture.filter(np.ascontiguousarray(quads, dtype=np.float64), **options), dtype=np.float32)


def filter(
    texture_path: _PathLike,
    quads: Any,
    chunk_rows: int = 65536,
    **options: Any,
) -> "dask.array.Array":
    """Filters a texture over footprints on the cluster: a lazy dask array.

    Parameters:
      texture_path: a ``.qtx`` file every worker can read (opened once per
        worker, memory-mapped).
      quads: a dask array ``(N, 4, 2)`` of footprints (texture space, as
        :meth:`quadtex.Texture.filter` takes), or a numpy array, split into
        chunks of ``chunk_rows`` rows.
      chunk_rows: rows a task when ``quads`` is not yet a dask array.
      options: passed to :meth:`quadtex.Texture.filter` (``wrap``,
        ``weighting``, ``error_bound``, …; not ``return_bound``).

    Returns: a dask array ``(N, 4)`` of float32, linear and premultiplied,
    chunked by rows like ``quads``; equal to ``Texture.filter`` on the whole
    array. Compute it with the client (``result.compute()``).

    Raises: ValueError for a shape other than ``(N, 4, 2)`` or
    ``return_bound`` (at once); the filter's own errors when computed.
    """
    import dask.array as da

    if "return_bound" in options:
        raise ValueError("return_bound is not supported by quadtex.dask.filter")
    texture_path = os.fspath(texture_path)
    if not isinstance(quads, da.Array):
        quads = da.from_array(np.asarray(quads, dtype=np.float64), chunks=(chunk_rows, 4, 2))
    if quads.ndim != 3 or quads.shape[1:] != (4, 2):
        raise ValueError(f"quads must have shape (N, 4, 2), got {quads.shape}")
    quads = quads.rechunk({1: 4, 2: 2})
    return da.map_blocks(
        _filter_block,
        quads,
        texture_path,
        options,
        dtype=np.float32,
        chunks=(quads.chunks[0], (4,)),
        drop_axis=2,
        name=f"quadtex-filter-{uuid.uuid4().hex[:8]}",
    )


def pack_tiles(
    client: "distributed.Client",
    tiles: _PathLike,
    out: _PathLike,
    tolerance: float = 0.0,
    memory_limit: Optional[int] = None,
    progress: bool = False,
) -> "quadtex.Texture":
    """Packs a folder of tiles on the cluster into one ``.qtx`` file.

    Each tile is packed by :func:`quadtex.pack_tile` on a worker; the client
    splices the packed tiles (:func:`quadtex.splice_tiles`, in Morton order,
    one in memory at a time) and writes ``out`` atomically: byte for byte
    the file ``quadtex pack-tiles TILES -o OUT`` writes.

    Parameters:
      client: a ``distributed.Client``.
      tiles: a folder of ``ROW_COL.png`` (or ``.jpg``) tiles every worker can
        read, as ``quadtex pack-tiles`` takes.
      out: the ``.qtx`` file to write.
      tolerance: in [0, 1], as for :func:`quadtex.pack_tiles`.
      memory_limit: bytes, per worker and on the client, or None.
      progress: show Dask's progress bar while the tiles are packed.

    Returns: the texture, as :func:`quadtex.pack_tiles` would.

    Raises: ValueError for a malformed folder (before any task runs), a
    damaged packed tile, or work above ``memory_limit``; whatever a tile's
    task raised.
    """
    tiles = os.fspath(tiles)
    token = uuid.uuid4().hex[:8]

    def submit(row: int, col: int, block_format: Optional[int]) -> "distributed.Future":
        """Tile ``(row, col)`` packed on a worker (in ``block_format`` when given)."""
        suffix = "" if block_format is None else f"-{block_format}"
        return client.submit(
            quadtex.pack_tile,
            tiles,
            row,
            col,
            tolerance,
            memory_limit,
            block_format,
            key=f"quadtex-tile-{row}-{col}{suffix}-{token}",
            retries=2,
        )

    # One batched submission (client.map) costs the client and scheduler
    # less than a submit a tile, which matters when they share the workers'
    # cores.
    cells = quadtex.mosaic_tiles(tiles)
    futures = dict(
        zip(
            cells,
            client.map(
                quadtex.pack_tile,
                [tiles] * len(cells),
                [row for row, _ in cells],
                [col for _, col in cells],
                [tolerance] * len(cells),
                [memory_limit] * len(cells),
                [None] * len(cells),
                key=[f"quadtex-tile-{row}-{col}-{token}" for row, col in cells],
                retries=2,
            ),
        )
    )
    if progress:
        from distributed import progress as show

        show(list(futures.values()))

    def load(row: int, col: int, block_format: Optional[int]) -> bytes:
        if block_format is None:
            # Release the worker's copy once the client holds it.
            return bytes(futures.pop((row, col)).result())
        return bytes(submit(row, col, block_format).result())

    try:
        texture = quadtex.splice_tiles(tiles, load, tolerance, memory_limit)
    finally:
        for future in futures.values():
            future.cancel()
    texture.save(out)
    return texture
