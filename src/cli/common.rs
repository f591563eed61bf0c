//! What several subcommands share: value parsers for their options, the
//! memory budget (`--memory-limit`), and the sizes and summaries their
//! reports print. Subcommand modules import from here (and from
//! [`super::output`] and [`super::comparison`]), never from each other.

use std::path::Path;

use quadtex_core::MAX_DEPTH;

/// A value parser: a tree level no deeper than [`MAX_DEPTH`]; `flag` names
/// the option in the error.
pub fn level(
    flag: &'static str,
) -> impl Fn(&str) -> std::result::Result<u8, String> + Clone + Send + Sync + 'static {
    move |text| {
        let v = text.parse::<u32>().map_err(|e| e.to_string())?;
        if v > u32::from(MAX_DEPTH) {
            return Err(format!("{flag} {v} exceeds the maximum depth {MAX_DEPTH}"));
        }
        Ok(v as u8)
    }
}

/// A value parser: an integer in `lo..=hi`; `flag` names the option in the error.
pub fn in_range(
    flag: &'static str,
    lo: u32,
    hi: u32,
) -> impl Fn(&str) -> std::result::Result<u32, String> + Clone + Send + Sync + 'static {
    move |text| {
        let v = text.parse::<u32>().map_err(|e| e.to_string())?;
        if !(lo..=hi).contains(&v) {
            return Err(format!("{flag} must be in {lo}..={hi}, got {v}"));
        }
        Ok(v)
    }
}

/// The memory budget, shared (flattened) by every command that loads or
/// builds textures.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct MemoryArgs {
    /// Memory budget for reading, decoding and packing textures: a size
    /// such as 512M, 4G, 1.5GiB or plain bytes (units are binary: K = KiB =
    /// 1024 bytes). Each step estimates its peak first and stops with an
    /// error naming the estimate when it is above the budget, instead of
    /// running out of memory. Default: the smallest of the cgroup memory
    /// limit, the address space left under `ulimit -v` and 3/4 of physical
    /// memory.
    #[arg(long, value_name = "SIZE", value_parser = memory_size)]
    memory_limit: Option<u64>,
}

impl MemoryArgs {
    /// The file limits with this budget.
    pub fn limits(&self) -> quadtex_io::Limits {
        let mut limits = quadtex_io::Limits::default();
        if let Some(bytes) = self.memory_limit {
            limits.max_memory = bytes;
        }
        limits
    }

    /// The budget in bytes (given or detected).
    pub fn bytes(&self) -> u64 {
        self.limits().max_memory
    }
}

/// Which files an SVG or glTF file may make quadtex read (its `<image
/// href>`s, its buffer and image URIs), shared (flattened) by every command
/// that reads SVG art or scenes.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct ResourcesArgs {
    /// Files an SVG's images or a glTF model's buffers and images may come
    /// from: same-folder (default: only inside the referring file's own
    /// folder; no absolute paths, no `..` or symbolic link out of it),
    /// anywhere (any readable file: only for files you trust) or none
    /// (only data: URIs, which are always read). A refused reference is an
    /// error naming the file and the reference.
    #[arg(long, value_name = "POLICY", default_value = "same-folder", value_parser = resources)]
    resources: quadtex_io::ExternalResources,
}

impl ResourcesArgs {
    /// `limits` with this policy.
    pub fn apply(&self, limits: quadtex_io::Limits) -> quadtex_io::Limits {
        quadtex_io::Limits {
            external_resources: self.resources,
            ..limits
        }
    }
}

/// A value parser: an external-resources policy, `same-folder`, `anywhere`
/// or `none`.
pub fn resources(text: &str) -> std::result::Result<quadtex_io::ExternalResources, String> {
    quadtex_io::ExternalResources::parse(text).ok_or_else(|| {
        format!(
            "--resources: unknown policy `{text}` (use {})",
            quadtex_io::ExternalResources::NAMES.join(", ")
        )
    })
}

/// Gives every texture of `scene` the memory budget for its raster baselines.
pub fn budget_scene(scene: &mut quadtex_render::Scene, bytes: u64) {
    for s in &mut scene.surfaces {
        s.texture = s.texture.take().map(|t| t.with_memory_budget(bytes));
    }
}

/// A value parser: a size in bytes, `512M`, `4G`, `1.5GiB`, `100000` (binary
/// units; `B`, `K`/`KB`/`KiB`, `M`…, `G`…, `T`…, case-insensitive).
pub fn memory_size(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        other => {
            return Err(format!(
                "--memory-limit: unknown unit `{other}` in `{text}` (use B, K, M, G or T)"
            ));
        }
    };
    let value: f64 = number.parse().map_err(|_| {
        format!("--memory-limit: `{text}` is not a size such as 512M, 4G or 1.5GiB")
    })?;
    let bytes = value * (1u64 << shift) as f64;
    if !(bytes >= 1.0 && bytes < 2f64.powi(63)) {
        return Err(format!(
            "--memory-limit: `{text}` must be at least one byte and below 8 EiB"
        ));
    }
    Ok(bytes.round() as u64)
}

/// Whether `path` names SVG art (by its extension).
pub fn is_svg(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
}

/// Bytes of an RGBA8 raster and of the raster with its full mip pyramid.
pub fn raster_bytes(width: u32, height: u32) -> (u64, u64) {
    let raster = 4 * u64::from(width) * u64::from(height);
    let (mut w, mut h, mut mips) = (u64::from(width), u64::from(height), 0u64);
    loop {
        mips += 4 * w * h;
        if w == 1 && h == 1 {
            break;
        }
        w = (w / 2).max(1);
        h = (h / 2).max(1);
    }
    (raster, mips)
}

/// `b` bytes in the largest binary unit it reaches (B, KiB, MiB, GiB).
pub fn human_bytes(b: u64) -> String {
    match b {
        b if b >= 1 << 30 => format!("{:.2} GiB", b as f64 / f64::from(1u32 << 30)),
        b if b >= 1 << 20 => format!("{:.2} MiB", b as f64 / f64::from(1u32 << 20)),
        b if b >= 1 << 10 => format!("{:.1} KiB", b as f64 / 1024.0),
        b => format!("{b} B"),
    }
}

/// `" + N texel blocks of 4x4"` for a tree with texel blocks, else empty.
pub fn blocks_summary(tree: &quadtex_core::QuadTree) -> String {
    tree.texel_blocks().map_or_else(String::new, |b| {
        let side = 1u32 << b.log2_side();
        format!(" + {} texel blocks of {side}x{side}", b.count())
    })
}

/// A value parser: a tolerance in [0, 1].
pub fn tolerance(text: &str) -> std::result::Result<f64, String> {
    let t = text.parse::<f64>().map_err(|e| e.to_string())?;
    if !(t.is_finite() && (0.0..=1.0).contains(&t)) {
        return Err(format!("--tolerance must be in [0, 1], got {t}"));
    }
    Ok(t)
}

/// What gradients cost in accuracy, when the art has any: the largest
/// deviation of a point from its square's colour, and the bound on stored
/// means (both linear, full scale 1).
pub fn smooth_summary(report: &quadtex_core::VectorReport) -> String {
    let mut leaves = if report.gradient_leaves > 0 {
        format!(
            "; {} gradient leaves ({} paints) keep their linear gradient: exact fragment integrals at any level",
            report.gradient_leaves, report.gradient_leaf_paints
        )
    } else {
        String::new()
    };
    if report.contour_leaves > 0 {
        leaves += &format!(
            "; {} contour leaves keep {} contour points: exact at any magnification",
            report.contour_leaves, report.contour_leaf_points
        );
        if report.crowded_leaves > 0 {
            leaves += &format!(
                " except in {} squares at the max level holding more edges than a contour leaf may (exact down to that level)",
                report.crowded_leaves
            );
        }
    }
    if report.max_smooth_deviation == 0.0 && report.max_mean_error == 0.0 {
        return leaves;
    }
    format!(
        "; gradients, images and masks: every point within {:.6} of its square's colour (at most --tolerance above --max-level), means within {:.2e} (linear){leaves}",
        report.max_smooth_deviation, report.max_mean_error
    )
}

/// The summary's words on a GeoTIFF's georeferencing (`; georeferenced:
/// EPSG:32633, tiepoint …, pixel scale …`), which the `.qtx` does not keep.
pub fn georeferenced(georeference: Option<&quadtex_io::GeoReference>) -> String {
    georeference.map_or(String::new(), |g| {
        format!("; georeferenced (not kept in the .qtx): {g}")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raster_and_mip_bytes() {
        assert_eq!(raster_bytes(4, 4), (64, 4 * (16 + 4 + 1)));
        assert_eq!(raster_bytes(4, 1), (16, 4 * (4 + 2 + 1)));
    }

    #[test]
    fn memory_sizes_parse() {
        assert_eq!(memory_size("512M"), Ok(512 << 20));
        assert_eq!(memory_size("4G"), Ok(4 << 30));
        assert_eq!(memory_size("4g"), Ok(4 << 30));
        assert_eq!(memory_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(memory_size("2 GB"), Ok(2 << 30));
        assert_eq!(memory_size("100000"), Ok(100_000));
        assert_eq!(memory_size("64KiB"), Ok(64 << 10));
        assert_eq!(memory_size("1T"), Ok(1 << 40));
        for bad in ["", "G", "0", "0.1", "-1G", "4X", "1e3", "nanG", "1..5G"] {
            assert!(memory_size(bad).is_err(), "{bad} accepted");
        }
        assert!(memory_size("4X").is_err_and(|e| e.contains("unknown unit `x`")));
    }

    #[test]
    fn level_and_range_parsers_name_the_option() {
        assert_eq!(level("--level")("30"), Ok(30));
        assert_eq!(
            level("--max-level")("99"),
            Err(format!(
                "--max-level 99 exceeds the maximum depth {MAX_DEPTH}"
            ))
        );
        assert!(level("--level")("x").is_err());
        assert_eq!(in_range("--width", 16, 3840)("16"), Ok(16));
        assert_eq!(
            in_range("--width", 16, 3840)("5"),
            Err("--width must be in 16..=3840, got 5".to_string())
        );
    }

    #[test]
    fn tolerance_must_be_a_fraction() {
        assert_eq!(tolerance("0.25"), Ok(0.25));
        assert_eq!(
            tolerance("-1"),
            Err("--tolerance must be in [0, 1], got -1".to_string())
        );
        assert!(tolerance("NaN").is_err_and(|e| e.contains("got NaN")));
        assert!(tolerance("two").is_err());
    }
}
