//! # quadtex-capi
//!
//! The C API of quadtex: open a packed `.qtx` texture or pack an image or
//! SVG file, filter pixel footprints, free the texture. The header
//! `include/quadtex.h` is generated from this crate by cbindgen
//! (`crates/quadtex-capi/check-header.sh` regenerates and compares it); the
//! documentation below is what the header carries.
//!
//! Unsafe code is confined to `ptr.rs` (pointer conversions, each checked
//! for NULL, alignment and size) and the `#[unsafe(no_mangle)]` attributes
//! of the exported functions, whose bodies are safe Rust run under a guard
//! that turns errors into statuses and panics into `QTX_STATUS_INTERNAL`.
#![deny(unsafe_code)]

mod error;
mod ops;
mod ptr;
#[cfg(test)]
mod tests;

use std::ffi::{c_char, c_int};

pub use error::QtxStatus;
use error::{Failure, guard};
use ptr::Out;

/// Special values of a level argument (a C enum rather than a macro, so
/// that the negative constant is a well-behaved expression).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum QtxLevel {
    /// Passed as `level` in `QtxFilterOptions` or as `max_level` to
    /// `qtx_pack`: choose automatically (the error bound picks the filter's
    /// level; packing uses the image's natural depth, or level 12 for SVG,
    /// lowered to fit the memory budget).
    Auto = -1,
}

/// Deepest level of a tree (a level-L square has side 2^-L of the texture).
pub const QTX_MAX_DEPTH: c_int = 30;

/// Deepest level SVG art can be packed at.
pub const QTX_MAX_SVG_LEVEL: c_int = 24;

/// The level SVG art is packed at when `qtx_pack` gets `QTX_LEVEL_AUTO`
/// (4096 x 4096 effective texels), unless its estimate is above the memory
/// budget: then the deepest level that fits, not below 8.
pub const QTX_DEFAULT_SVG_LEVEL: c_int = 12;

/// A packed texture (an incomplete quadtree). Opaque: create it with
/// `qtx_open` or `qtx_pack`, release it with `qtx_free`. Filtering does not
/// modify it, so one texture may be filtered from several threads at once.
pub struct QtxTexture {
    texture: quadtex_core::Texture,
}

/// How texture space continues beyond the unit square along one axis
/// (values for `QtxFilterOptions.wrap_x` and `.wrap_z`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum QtxWrapMode {
    /// Tiles repeat: the texture at x is the texture at x - floor(x).
    Repeat = 0,
    /// The edge extends outwards: beyond an edge the texture is its
    /// outermost finest cell along that edge, stretched.
    Clamp = 1,
    /// Tiles repeat reflected: [1, 2) is [0, 1) mirrored, period 2.
    Mirror = 2,
    /// Beyond the unit square the texture is `QtxFilterOptions.border`.
    Border = 3,
}

/// Which files an SVG's `<image href>` may read (values for
/// `QtxSvgOptions.resources`). Data URIs are always read; remote URLs never.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum QtxResources {
    /// Only files inside the SVG's own folder: no absolute path, no `..` or
    /// symbolic link out of it (the default).
    SameFolder = 0,
    /// Any file the process may read (for trusted files).
    Anywhere = 1,
    /// No files, not even beside the SVG: data URIs only.
    None = 2,
}

/// How a footprint's points are weighted in its mean colour (values for
/// `QtxFilterOptions.weighting`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum QtxWeighting {
    /// Uniform over the pixel square (a screen-space box filter): texture
    /// area is weighed by the screen area that sees it, from the projective
    /// map the footprint's four corners fix. The right choice for a renderer.
    Screen = 0,
    /// Uniform over the footprint in texture space.
    Texture = 1,
}

/// Options of `qtx_filter`. Start from `qtx_filter_options_default()` and
/// change fields; every field is checked by `qtx_filter`, which names the
/// field at fault.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QtxFilterOptions {
    /// A `QtxWrapMode`: how the texture continues along x (default repeat).
    pub wrap_x: c_int,
    /// A `QtxWrapMode`: how the texture continues along z (default repeat).
    pub wrap_z: c_int,
    /// The colour beyond the unit square on a `QTX_WRAP_MODE_BORDER` axis:
    /// linear, premultiplied RGBA, finite (default transparent 0, 0, 0, 0).
    pub border: [f32; 4],
    /// A `QtxWeighting` (default `QTX_WEIGHTING_SCREEN`).
    pub weighting: c_int,
    /// When `level` is `QTX_LEVEL_AUTO`: the error bound each footprint aims
    /// at, relative to the texture's contrast, finite and > 0 (default
    /// 1/512, half an 8-bit step): squares are refined, largest error
    /// first, until it is met or 64 squares are spent. Checked even when
    /// `level` is fixed.
    pub error_bound: f64,
    /// `QTX_LEVEL_AUTO` (-1, the default) to refine by `error_bound`, or a
    /// fixed level in 0..=`QTX_MAX_DEPTH` (clamped to the texture's depth)
    /// every square is refined to.
    pub level: c_int,
    /// Threads a batch runs on: 0 (the default) for one a core, or at
    /// least 1 (1 runs on the calling thread only, for callers that run
    /// batches on threads of their own). The colours are bit-identical
    /// whatever the count.
    pub threads: c_int,
}

/// Options of `qtx_pack_svg`. Start from `qtx_svg_options_default()` and
/// change fields; `qtx_pack_svg` checks each and names the field at fault.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QtxSvgOptions {
    /// `QTX_LEVEL_AUTO` (-1, the default) for `QTX_DEFAULT_SVG_LEVEL` (12;
    /// 20 with contour leaves, where squares split only while they hold
    /// more edges than the budget), lowered (not below 8) when the
    /// packing's estimate is above the memory budget, as `quadtex pack`
    /// does; or a level in 0..=`QTX_MAX_SVG_LEVEL`, kept: art that does
    /// not fit at it is refused with `QTX_STATUS_LIMIT`.
    pub max_level: c_int,
    /// 0 (the default) for none, or 3..=1024: squares of flat art crossed by
    /// at most this many edges keep their contours, exact at any
    /// magnification (queries then reach level 30).
    pub contour_leaves: c_int,
    /// The most steps the exact coverage sweep may take (pairs of edges
    /// tested for a crossing plus edges handed to each slab), at least 1;
    /// default 2^31, about a minute where steps are dearest. Art needing
    /// more (thousands of dashes piled on a point) is refused with
    /// `QTX_STATUS_LIMIT`, the message naming the steps it needs.
    pub max_sweep_work: u64,
    /// Memory budget in bytes (`quadtex pack --memory-limit`), or 0 (the
    /// default) for the detected budget: art whose rasterisation is
    /// estimated above it is refused with `QTX_STATUS_LIMIT`.
    pub memory_limit: u64,
    /// A `QtxResources`: which files the art's images may come from
    /// (default `QTX_RESOURCES_SAME_FOLDER`: only inside the SVG's own
    /// folder). A refused reference is `QTX_STATUS_LIMIT`, the message
    /// naming the SVG and the reference.
    pub resources: c_int,
}

/// What `qtx_texture_info` reports.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QtxTextureInfo {
    /// Depth of the tree: the level of its finest squares.
    pub depth: u32,
    /// Columns of the finest grid over the texture (`2^depth` for a square
    /// texture; a strip packs its own shape, fewer along its short side).
    pub columns: u64,
    /// Rows of the finest grid over the texture.
    pub rows: u64,
    /// How nodes store colour: 1 = unorm16 (LDR, channels in `[0, 1]`),
    /// 2 = half floats (HDR: OpenEXR and Radiance sources, unclamped).
    pub colour_format: u32,
    /// Nodes in the tree.
    pub node_count: u64,
    /// Bytes the tree occupies in memory.
    pub memory_bytes: u64,
    /// The mean colour over the unit square (linear, premultiplied RGBA):
    /// what a footprint covering many whole tiles of a repeating texture
    /// filters to.
    pub mean: [f32; 4],
}

/// The message describing why the last failed `qtx_*` call on this thread
/// failed (it names the file, the option or the quad and corner at fault),
/// or NULL if the last call succeeded. The string belongs to the library:
/// it stays valid until the next `qtx_*` call on the same thread; copy it to
/// keep it.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub extern "C" fn qtx_last_error() -> *const c_char {
    error::last_error_ptr()
}

/// The default filter options: repeat on both axes, transparent border,
/// screen weighting, error bound 1/512, `QTX_LEVEL_AUTO`.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub extern "C" fn qtx_filter_options_default() -> QtxFilterOptions {
    ops::default_options()
}

/// The default SVG packing options: `QTX_LEVEL_AUTO`, no contour leaves,
/// a sweep budget of 2^31 steps, the detected memory budget, images only
/// from the SVG's own folder.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub extern "C" fn qtx_svg_options_default() -> QtxSvgOptions {
    ops::default_svg_options()
}

/// Opens a packed texture: a `.qtx` file written by `quadtex pack`. The file
/// is read whole and validated; the texture repeats (the filter options
/// choose the wrap).
///
/// `path` is a NUL-terminated file name (any bytes on Unix; UTF-8
/// elsewhere). On success `*out` receives a texture to release with
/// `qtx_free`; on failure `*out` is set to NULL (if `out` is not NULL).
///
/// Returns `QTX_STATUS_OK`; `QTX_STATUS_INVALID_ARGUMENT` (NULL or empty
/// `path`, NULL `out`), `QTX_STATUS_IO`, `QTX_STATUS_FORMAT` (not a valid
/// `.qtx` file: the message names the field), `QTX_STATUS_LIMIT`.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string; `out` is NULL or valid for
/// writing a pointer.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub unsafe extern "C" fn qtx_open(path: *const c_char, out: *mut *mut QtxTexture) -> QtxStatus {
    // SAFETY: forwarded from this function's contract.
    unsafe { open_with(path, out, ops::open) }
}

/// `qtx_open` and the `qtx_open_mapped` functions: `open` makes the
/// texture from the path.
///
/// # Safety
/// As `qtx_open`.
#[allow(unsafe_code)]
unsafe fn open_with(
    path: *const c_char,
    out: *mut *mut QtxTexture,
    open: fn(&std::path::Path) -> Result<QtxTexture, Failure>,
) -> QtxStatus {
    guard(|| {
        // SAFETY: `out` is NULL or writable, by the caller's contract.
        let mut out = unsafe { Out::new(out, "out") }?;
        out.set(std::ptr::null_mut());
        // SAFETY: `path` is NULL or NUL-terminated, by the caller's contract.
        let path = unsafe { ptr::path_arg(path, "path") }?;
        out.set(ptr::into_raw(open(&path)?));
        Ok(())
    })
}

/// Opens a `.qtx` file by memory-mapping it: the header, the structure and
/// the payload checksum are checked (one pass over the file at memory
/// speed, so a damaged colour or texel is refused with
/// `QTX_STATUS_FORMAT`, the message naming the file and the damaged
/// bytes), and filtering reads the nodes it touches. The colours'
/// invariants are not checked: `qtx_verify` checks them. The file must not
/// be truncated or rewritten in place while the texture lives (quadtex's
/// writers replace files by renaming, which is safe).
///
/// Arguments, returns and safety as `qtx_open`.
///
/// # Safety
/// As `qtx_open`.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub unsafe extern "C" fn qtx_open_mapped(
    path: *const c_char,
    out: *mut *mut QtxTexture,
) -> QtxStatus {
    // SAFETY: forwarded from this function's contract.
    unsafe { open_with(path, out, ops::open_mapped) }
}

/// As `qtx_open_mapped` without the payload checksum, for trusted files:
/// only the header and the structure are checked (time and memory
/// proportional to 1/64 of the file). This gives up the promise that a
/// damaged file is refused: a corrupt colour is filtered as it is, until
/// `qtx_verify` is asked.
///
/// Arguments, returns and safety as `qtx_open`.
///
/// # Safety
/// As `qtx_open`.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub unsafe extern "C" fn qtx_open_mapped_unverified(
    path: *const c_char,
    out: *mut *mut QtxTexture,
) -> QtxStatus {
    // SAFETY: forwarded from this function's contract.
    unsafe { open_with(path, out, ops::open_mapped_unverified) }
}

/// Checks every colour and texel of a texture (what `qtx_open_mapped`
/// leaves unread): premultiplied colours, each inner colour the mean of
/// its children, each texel block the mean of its texels.
///
/// Returns `QTX_STATUS_OK`; `QTX_STATUS_INVALID_ARGUMENT` (NULL
/// `texture`); `QTX_STATUS_FORMAT`, the message naming the first node that
/// fails.
///
/// # Safety
/// `texture` is NULL or a live texture from `qtx_open` / `qtx_pack`.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub unsafe extern "C" fn qtx_verify(texture: *const QtxTexture) -> QtxStatus {
    guard(|| {
        // SAFETY: `texture` is NULL or live, by this function's contract.
        let texture = unsafe { ptr::ref_arg(texture, "texture") }?;
        texture.texture.tree().verify()?;
        Ok(())
    })
}

/// Packs an image or SVG art into a texture, as `quadtex pack` does.
///
/// * PNG, JPEG or OpenEXR: cells within `tolerance` (in [0, 1]: the largest
///   per-channel deviation, linear premultiplied, 0 = lossless) of their
///   square's colour are merged; `max_level` in 0..=`QTX_MAX_DEPTH` limits
///   the depth, `QTX_LEVEL_AUTO` (or any negative value) keeps the image's
///   natural depth.
/// * SVG (`.svg`, any case): packed exactly; `tolerance` must be 0;
///   `max_level` in 0..=`QTX_MAX_SVG_LEVEL`, negative for
///   `QTX_DEFAULT_SVG_LEVEL` (12), lowered (not below 8) when the
///   packing's estimate is above the memory budget.
///
/// `memory_limit`: the memory budget in bytes decoding and packing may use
/// (`quadtex pack --memory-limit`), or 0 for the detected budget (the
/// smallest of the cgroup's limit, the address space left and 3/4 of
/// physical memory, as the CLI's default); work estimated above it is
/// refused with `QTX_STATUS_LIMIT` before it allocates, the message naming
/// the estimate and the budget.
///
/// `path` and `out` as for `qtx_open`. Returns `QTX_STATUS_OK`;
/// `QTX_STATUS_INVALID_ARGUMENT` (NULL pointers, tolerance or level out of
/// range), `QTX_STATUS_IO`, `QTX_STATUS_FORMAT` (an image that does not
/// decode, SVG that does not parse), `QTX_STATUS_UNSUPPORTED` (SVG features
/// not supported: filters, GIF/WebP/svgz images, patterns over too many
/// tiles),
/// `QTX_STATUS_LIMIT` (also an SVG image outside the SVG's folder: `qtx_pack`
/// reads images only from there; `qtx_pack_svg` takes
/// `options.resources`). SVG gradients are packed to the default smooth-colour
/// tolerance (a quarter of an 8-bit step; `tolerance` must be 0 for SVG).
///
/// # Safety
/// As `qtx_open`.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub unsafe extern "C" fn qtx_pack(
    path: *const c_char,
    tolerance: f64,
    max_level: c_int,
    memory_limit: u64,
    out: *mut *mut QtxTexture,
) -> QtxStatus {
    guard(|| {
        // SAFETY: `out` is NULL or writable, by this function's contract.
        let mut out = unsafe { Out::new(out, "out") }?;
        out.set(std::ptr::null_mut());
        // SAFETY: `path` is NULL or NUL-terminated, by this function's contract.
        let path = unsafe { ptr::path_arg(path, "path") }?;
        out.set(ptr::into_raw(ops::pack(
            &path,
            tolerance,
            max_level,
            memory_limit,
        )?));
        Ok(())
    })
}

/// Packs SVG art into a texture with `options` (NULL for
/// `qtx_svg_options_default()`), as `quadtex pack` does with
/// `--max-level`, `--contour-leaves` and `--max-sweep-work`. The file must
/// be SVG (`.svg`, any case).
///
/// `path` and `out` as for `qtx_open`. Returns `QTX_STATUS_OK`;
/// `QTX_STATUS_INVALID_ARGUMENT` (NULL `path` or `out`, a file that is not
/// `.svg`, an option out of range: the message names the field,
/// `options.contour_leaves`), and otherwise as `qtx_pack`; art beyond
/// `options.max_sweep_work` is `QTX_STATUS_LIMIT`.
///
/// # Safety
/// As `qtx_open`; `options` is NULL or points to a `QtxSvgOptions`.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub unsafe extern "C" fn qtx_pack_svg(
    path: *const c_char,
    options: *const QtxSvgOptions,
    out: *mut *mut QtxTexture,
) -> QtxStatus {
    guard(|| {
        // SAFETY: `out` is NULL or writable, by this function's contract.
        let mut out = unsafe { Out::new(out, "out") }?;
        out.set(std::ptr::null_mut());
        // SAFETY: `path` is NULL or NUL-terminated, by this function's contract.
        let path = unsafe { ptr::path_arg(path, "path") }?;
        // SAFETY: `options` is NULL or a readable struct, by contract.
        let options = unsafe { ptr::optional_ref_arg(options, "options") }?
            .copied()
            .unwrap_or_else(ops::default_svg_options);
        out.set(ptr::into_raw(ops::pack_svg(&path, &options)?));
        Ok(())
    })
}

/// Packs a folder of raster tiles into one texture, one tile in memory at a
/// time: tiles named `ROW_COL.png` (or `.jpg`; row 0 at the top) forming a
/// complete grid of 1, 2, 4, … tiles a side, every tile the same square of
/// a power of two texels. The texture is the one `qtx_pack` would make of
/// the whole mosaic. `tolerance` and `memory_limit` as for `qtx_pack` (0 =
/// lossless; 0 = the detected memory budget).
///
/// `dir` (NUL-terminated) and `out` as for `qtx_open`. Returns
/// `QTX_STATUS_OK`; `QTX_STATUS_INVALID_ARGUMENT` (NULL pointers, tolerance
/// out of range), `QTX_STATUS_IO`, `QTX_STATUS_FORMAT` (a missing,
/// duplicate, odd-sized or undecodable tile, named in the message),
/// `QTX_STATUS_LIMIT`.
///
/// # Safety
/// As `qtx_open`, with `dir` for `path`.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub unsafe extern "C" fn qtx_pack_tiles(
    dir: *const c_char,
    tolerance: f64,
    memory_limit: u64,
    out: *mut *mut QtxTexture,
) -> QtxStatus {
    guard(|| {
        // SAFETY: `out` is NULL or writable, by this function's contract.
        let mut out = unsafe { Out::new(out, "out") }?;
        out.set(std::ptr::null_mut());
        // SAFETY: `dir` is NULL or NUL-terminated, by this function's contract.
        let dir = unsafe { ptr::path_arg(dir, "dir") }?;
        out.set(ptr::into_raw(ops::pack_tiles(
            &dir,
            tolerance,
            memory_limit,
        )?));
        Ok(())
    })
}

/// Filters `n` pixel footprints: the mean colour of the texture over each.
///
/// A footprint is the texture-space image of a pixel square: its four
/// corners, the images of the pixel corners (0,0), (1,0), (1,1), (0,1) in
/// that order (pixel x right, y down the screen). Texture space is the unit
/// square [0,1)^2 with x to the right and z up (an image's top row is at
/// z near 1); corners may lie anywhere, the wrap modes say what lies outside.
/// `quads` holds `8 n` doubles: quad i, corner c, axis a (0 = x, 1 = z) is
/// `quads[8 i + 2 c + a]`.
///
/// `out_rgba` receives `4 n` floats: quad i's colour, linear light,
/// premultiplied alpha, is `out_rgba[4 i .. 4 i + 3]` (r, g, b, a).
/// `options` may be NULL for `qtx_filter_options_default()`.
///
/// Every quad and option is checked before anything is filtered: on failure
/// `out_rgba` is untouched. Returns `QTX_STATUS_OK`, or
/// `QTX_STATUS_INVALID_ARGUMENT`: NULL `texture`, NULL `quads` or
/// `out_rgba` with `n > 0` (both may be NULL when `n` is 0), misaligned or
/// overlapping buffers, an option out of range (the message names the field,
/// `options.error_bound`), a NaN or infinite coordinate (the message names the
/// quad and the field, `quad 3: coordinate corner[2].z is not finite (NaN)`),
/// a coordinate beyond 1e15 in magnitude (MAX_TEXTURE_COORDINATE) or a quad
/// that crosses itself (a bow tie), each naming the quad.
///
/// Each colour is within `options.error_bound` of the exact mean (relative
/// to the texture's contrast), whatever the footprint's size; use
/// `qtx_filter_with_bounds` for the bound each quad reached. The batch runs
/// on every core unless `options.threads` says how many threads; the
/// colours are bit-identical whatever the count.
///
/// # Safety
/// `texture` is NULL or a live texture from `qtx_open` / `qtx_pack`;
/// `quads` is NULL or points to `8 n` readable doubles; `out_rgba` is NULL
/// or points to `4 n` writable floats; `options` is NULL or points to a
/// `QtxFilterOptions`.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub unsafe extern "C" fn qtx_filter(
    texture: *const QtxTexture,
    quads: *const f64,
    n: usize,
    options: *const QtxFilterOptions,
    out_rgba: *mut f32,
) -> QtxStatus {
    // SAFETY: the same contract, with no bounds asked for.
    unsafe { qtx_filter_with_bounds(texture, quads, n, options, out_rgba, std::ptr::null_mut()) }
}

/// As `qtx_filter`, and when `out_bounds` is not NULL, writes each quad's
/// error bound to `out_bounds[i]`: every channel of quad i's colour is
/// within `out_bounds[i]` times the texture's contrast (1 for 8- and
/// 16-bit textures, the widest channel range for HDR ones) of the exact
/// mean, 0 when exact. Under an error bound it is at most
/// `options.error_bound` (the refinement stops only at a hard cap of
/// `2^20` squares a footprint, and then reports the larger bound reached).
///
/// Returns as `qtx_filter`; also `QTX_STATUS_INVALID_ARGUMENT` when
/// `out_bounds` is misaligned or overlaps `quads` or `out_rgba`.
///
/// # Safety
/// As `qtx_filter`; `out_bounds` is NULL or points to `n` writable doubles.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub unsafe extern "C" fn qtx_filter_with_bounds(
    texture: *const QtxTexture,
    quads: *const f64,
    n: usize,
    options: *const QtxFilterOptions,
    out_rgba: *mut f32,
    out_bounds: *mut f64,
) -> QtxStatus {
    guard(|| {
        // SAFETY: `texture` is NULL or live, by this function's contract.
        let texture = unsafe { ptr::ref_arg(texture, "texture") }?;
        // SAFETY: `options` is NULL or a readable struct, by contract.
        let options = unsafe { ptr::optional_ref_arg(options, "options") }?
            .copied()
            .unwrap_or_else(ops::default_options);
        let too_many = || Failure::invalid(format!("n = {n} quads do not fit in memory"));
        let (quad_len, out_len) = (
            n.checked_mul(8).ok_or_else(too_many)?,
            n.checked_mul(4).ok_or_else(too_many)?,
        );
        // Checked here, before slices exist: Rust must not see a mutable
        // slice aliasing another.
        let buffers = [
            (
                "quads",
                quads.addr(),
                quad_len.saturating_mul(8),
                quads.is_null(),
            ),
            (
                "out_rgba",
                out_rgba.addr(),
                out_len.saturating_mul(4),
                out_rgba.is_null(),
            ),
            (
                "out_bounds",
                out_bounds.addr(),
                n.saturating_mul(8),
                out_bounds.is_null(),
            ),
        ];
        for (i, a) in buffers.iter().enumerate() {
            for b in &buffers[i + 1..] {
                if !a.3 && !b.3 && ops::overlap(a.1, a.2, b.1, b.2) {
                    return Err(Failure::invalid(format!("{} and {} overlap", a.0, b.0)));
                }
            }
        }
        // SAFETY: `quads` is NULL or holds 8 n readable doubles, by contract;
        // it does not overlap the outputs (checked).
        let quads = unsafe { ptr::slice_arg(quads, quad_len, "quads") }?;
        // SAFETY: `out_rgba` is NULL or holds 4 n writable floats, by
        // contract; it does not overlap `quads` or `out_bounds` (checked).
        let out = unsafe { ptr::slice_mut_arg(out_rgba, out_len, "out_rgba") }?;
        let bounds = if out_bounds.is_null() {
            None
        } else {
            // SAFETY: `out_bounds` holds n writable doubles, by contract; it
            // overlaps neither other buffer (checked).
            Some(unsafe { ptr::slice_mut_arg(out_bounds, n, "out_bounds") }?)
        };
        ops::filter(texture, quads, &options, out, bounds)
    })
}

/// Fills `*out` with the texture's depth, size and mean colour.
///
/// Returns `QTX_STATUS_OK`, or `QTX_STATUS_INVALID_ARGUMENT` if `texture`
/// or `out` is NULL.
///
/// # Safety
/// `texture` is NULL or a live texture; `out` is NULL or writable.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub unsafe extern "C" fn qtx_texture_info(
    texture: *const QtxTexture,
    out: *mut QtxTextureInfo,
) -> QtxStatus {
    guard(|| {
        // SAFETY: `out` is NULL or writable, by this function's contract.
        let mut out = unsafe { Out::new(out, "out") }?;
        // SAFETY: `texture` is NULL or live, by this function's contract.
        let texture = unsafe { ptr::ref_arg(texture, "texture") }?;
        out.set(ops::info(texture));
        Ok(())
    })
}

/// Releases a texture from `qtx_open` or `qtx_pack`. NULL is ignored.
///
/// # Safety
/// `texture` is NULL or a texture not yet released, which no other thread
/// is using; it must not be used afterwards.
#[unsafe(no_mangle)]
#[allow(unsafe_code)]
pub unsafe extern "C" fn qtx_free(texture: *mut QtxTexture) {
    // Dropping a tree does not panic; no guard is needed (nor wanted: freeing
    // keeps the last error of the call before it).
    // SAFETY: by this function's contract, `texture` is NULL or came from
    // `ptr::into_raw` in `qtx_open` / `qtx_pack` and is released once.
    unsafe { ptr::release(texture) }
}
