use std::sync::OnceLock;

/// Resource limits applied while reading files, checked before any
/// allocation they bound. The defaults suit this project's 24 GiB machines;
/// embedders lower them (`Limits { max_nodes: 1 << 20, ..Limits::default() }`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest image width or height, in texels (default 32768, the raster
    /// builder's deepest grid).
    pub max_dimension: u32,
    /// Largest input file, in bytes (default 16 GiB).
    pub max_file_bytes: u64,
    /// Most nodes in a tree (default [`quadtex_core::MAX_NODES`], 2³¹).
    pub max_nodes: u64,
    /// Deepest tree level (default [`quadtex_core::MAX_DEPTH`], 30).
    pub max_depth: u8,
    /// Most elements in an SVG document, counted with every `use` expanded
    /// (default 100 000; `usvg` itself stops at 1 000 000).
    pub max_svg_elements: u64,
    /// Most image texels one SVG may draw, every copy (pattern tile, `use`)
    /// counted (default 2²⁸: sixteen copies of a 4096² image). Packing
    /// visits an image's texels once per level for every square it covers,
    /// so this bounds the time images take.
    pub max_svg_image_texels: u64,
    /// Most shapes in a scene (default 10 000).
    pub max_scene_shapes: usize,
    /// Most triangles in one mesh of a scene (default 2²² = 4 194 304,
    /// about 1.4 GiB at the renderer's 352 bytes a triangle with its
    /// bounding-volume hierarchy and edge neighbours; a mesh must also fit [`Limits::max_memory`]).
    pub max_mesh_triangles: usize,
    /// Memory budget in bytes for one decode, build or read (default
    /// [`default_memory_budget`]: the smallest of the cgroup's memory limit,
    /// the address space left under `RLIMIT_AS`, and 3/4 of physical
    /// memory). Each builder and reader estimates its peak before
    /// allocating and refuses work above the budget with
    /// [`crate::Error::MemoryBudget`] (the command line's `--memory-limit`
    /// sets it). Estimates: decoding an image, the decoder's buffer plus 8
    /// bytes a texel (a TIFF: twice one strip or tile, plus 12 bytes a
    /// texel at 8 bits, 8 at 16); packing a raster, see
    /// [`quadtex_core::raster_grid_bytes`]; packing SVG, see
    /// [`quadtex_core::VectorArt::estimate_bytes`]; reading a `.qtx`,
    /// [`QTX_READ_BYTES_PER_NODE`] a node.
    pub max_memory: u64,
    /// Which files an SVG's `<image href>` and a glTF model's buffer and
    /// image URIs may read (default [`ExternalResources::SameFolder`]: only
    /// files inside the referring file's own folder). Data URIs are always
    /// read; remote URLs never are.
    pub external_resources: ExternalResources,
}

/// Which files outside itself an SVG or glTF file may make quadtex read,
/// through an SVG's `<image href="…">` or a glTF model's buffer and image
/// `uri`s. Data URIs (`data:…`) are inside the file and always allowed;
/// remote URLs (`…://…`) are never fetched, whatever the policy. A refused
/// reference is [`crate::Error::ExternalResource`], naming the file and the
/// reference.
///
/// It is a plain `Copy` enum, so [`Limits`] and [`crate::SvgOptions`] stay
/// `Copy`; a list of extra folders would need an allocation in every
/// `Limits`. To read from another folder, use [`ExternalResources::Anywhere`]
/// for files you trust, or copy the resources beside the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ExternalResources {
    /// Only files inside the referring file's folder or its subfolders: no
    /// absolute paths, no `..` out of it, no symbolic link leading out
    /// (the reference is resolved with every link followed, then checked
    /// against the folder, itself resolved). The default: a downloaded file
    /// reads only what came with it.
    #[default]
    SameFolder,
    /// Any file the process may read, relative paths resolved against the
    /// referring file's folder (quadtex's behaviour before this policy).
    Anywhere,
    /// No files at all, not even beside the referring file: only data URIs.
    None,
}

impl ExternalResources {
    /// The names [`ExternalResources::parse`] accepts, as the command line
    /// spells them: `same-folder`, `anywhere`, `none`.
    pub const NAMES: [&'static str; 3] = ["same-folder", "anywhere", "none"];

    /// The policy named `name` (`same-folder`, `anywhere` or `none`).
    pub fn parse(name: &str) -> Option<ExternalResources> {
        match name {
            "same-folder" => Some(ExternalResources::SameFolder),
            "anywhere" => Some(ExternalResources::Anywhere),
            "none" => Some(ExternalResources::None),
            _ => None,
        }
    }

    /// This policy's name, as [`ExternalResources::parse`] reads it.
    pub fn name(self) -> &'static str {
        match self {
            ExternalResources::SameFolder => "same-folder",
            ExternalResources::Anywhere => "anywhere",
            ExternalResources::None => "none",
        }
    }

    /// The file that `reference` (a path relative to `document`'s folder,
    /// or absolute; not a data URI or URL) names, if this policy lets
    /// `document` read it. Under [`ExternalResources::SameFolder`] the
    /// path returned is the resolved one (links followed), so the file
    /// read is the file checked. A refusal, or a file that does not exist
    /// under `SameFolder` (it cannot be resolved), is an error naming
    /// `document` and `reference`.
    pub fn resolve(
        self,
        document: &std::path::Path,
        reference: &str,
    ) -> Result<std::path::PathBuf, crate::Error> {
        let refuse = |reason: String| crate::Error::ExternalResource {
            path: document.to_path_buf(),
            reference: reference.to_string(),
            reason,
        };
        let folder = match document.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => std::path::Path::new("."),
        };
        let named = std::path::Path::new(reference);
        match self {
            ExternalResources::Anywhere => Ok(folder.join(named)),
            ExternalResources::None => Err(refuse(
                "external files are not read (resources policy `none`; data URIs only)".into(),
            )),
            ExternalResources::SameFolder => {
                if named.has_root() || named.is_absolute() {
                    return Err(refuse(
                        "an absolute path, outside the file's folder (resources policy `same-folder`)"
                            .into(),
                    ));
                }
                let root = folder.canonicalize().map_err(|e| {
                    refuse(format!(
                        "the file's folder {} cannot be resolved: {e}",
                        folder.display()
                    ))
                })?;
                // A missing or unreadable file is the read error it would
                // have been under any policy.
                let joined = folder.join(named);
                let file = joined.canonicalize().map_err(crate::error::io(&joined))?;
                if !file.starts_with(&root) {
                    return Err(refuse(format!(
                        "it resolves to {}, outside the file's folder {} (resources policy `same-folder`)",
                        file.display(),
                        root.display()
                    )));
                }
                Ok(file)
            }
        }
    }
}

/// Peak bytes per node while reading a `.qtx`: the file's bytes (8.125 a
/// node), which the tree reads its colours from in place, and the tree's
/// inner flags with their rank counters (0.25), rounded up.
/// ([`crate::map_qtx`] needs only the 0.25.)
pub const QTX_READ_BYTES_PER_NODE: u64 = 9;

/// The memory budget when neither a cgroup limit, an address-space limit
/// nor `/proc/meminfo` can be read: 4 GiB.
pub const FALLBACK_MEMORY_BUDGET: u64 = 4 << 30;

impl Limits {
    /// Refuses an image whose width or height is above
    /// [`Limits::max_dimension`].
    pub(crate) fn check_dimensions(
        &self,
        path: &std::path::Path,
        width: u32,
        height: u32,
    ) -> Result<(), crate::Error> {
        match [width, height]
            .into_iter()
            .find(|&v| v > self.max_dimension)
        {
            Some(v) => Err(crate::Error::Limit {
                path: path.to_path_buf(),
                limit: "max_dimension",
                value: v.into(),
                max: self.max_dimension.into(),
            }),
            None => Ok(()),
        }
    }

    /// Refuses a file of `len` bytes above [`Limits::max_file_bytes`].
    pub(crate) fn check_file_size(
        &self,
        path: &std::path::Path,
        len: u64,
    ) -> Result<(), crate::Error> {
        if len > self.max_file_bytes {
            return Err(crate::Error::Limit {
                path: path.to_path_buf(),
                limit: "max_file_bytes",
                value: len,
                max: self.max_file_bytes,
            });
        }
        Ok(())
    }

    /// Refuses `estimate` bytes for `what` above [`Limits::max_memory`].
    pub(crate) fn check_memory(
        &self,
        path: &std::path::Path,
        what: impl FnOnce() -> String,
        estimate: u64,
        knobs: &'static str,
    ) -> Result<(), crate::Error> {
        if estimate > self.max_memory {
            return Err(crate::Error::MemoryBudget {
                path: path.to_path_buf(),
                what: what(),
                estimate,
                budget: self.max_memory,
                knobs,
            });
        }
        Ok(())
    }
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_dimension: 32768,
            max_file_bytes: 16 << 30,
            max_nodes: quadtex_core::MAX_NODES,
            max_depth: quadtex_core::MAX_DEPTH,
            max_svg_elements: 100_000,
            max_svg_image_texels: 1 << 28,
            max_scene_shapes: 10_000,
            external_resources: ExternalResources::SameFolder,
            max_mesh_triangles: 1 << 22,
            max_memory: default_memory_budget(),
        }
    }
}

/// The default memory budget, detected once per process: the smallest of
///
/// * the cgroup's limit (v2 `memory.max` of the process's cgroup or of the
///   root, v1 `memory/memory.limit_in_bytes`; `max` or a huge v1 value is no
///   limit),
/// * the address space left under `RLIMIT_AS` (the soft limit in
///   `/proc/self/limits` less the process's current `VmSize`),
/// * 3/4 of physical memory (`MemTotal` in `/proc/meminfo`),
///
/// or [`FALLBACK_MEMORY_BUDGET`] when none of them can be read (not Linux).
pub fn default_memory_budget() -> u64 {
    static BUDGET: OnceLock<u64> = OnceLock::new();
    *BUDGET.get_or_init(detect_memory_budget)
}

fn read(path: &str) -> Option<String> {
    std::fs::read_to_string(path).ok()
}

fn detect_memory_budget() -> u64 {
    let cgroup = cgroup_limit();
    let address_space = read("/proc/self/limits")
        .and_then(|t| parse_address_space_limit(&t))
        .map(|limit| {
            let used = read("/proc/self/status")
                .and_then(|t| parse_kib_field(&t, "VmSize:"))
                .unwrap_or(0);
            limit.saturating_sub(used)
        });
    let physical = read("/proc/meminfo")
        .and_then(|t| parse_kib_field(&t, "MemTotal:"))
        .map(|total| total / 4 * 3);
    [cgroup, address_space, physical]
        .into_iter()
        .flatten()
        .min()
        .unwrap_or(FALLBACK_MEMORY_BUDGET)
}

/// The cgroup (v2, then v1) memory limit of this process, if any.
fn cgroup_limit() -> Option<u64> {
    let mut candidates = Vec::new();
    if let Some(own) = read("/proc/self/cgroup").and_then(|t| {
        t.lines()
            .find_map(|l| l.strip_prefix("0::").map(str::to_string))
    }) {
        let own = own.trim().trim_start_matches('/');
        if !own.is_empty() {
            candidates.push(format!("/sys/fs/cgroup/{own}/memory.max"));
        }
    }
    candidates.push("/sys/fs/cgroup/memory.max".into());
    candidates.push("/sys/fs/cgroup/memory/memory.limit_in_bytes".into());
    candidates
        .iter()
        .filter_map(|p| read(p))
        .filter_map(|t| parse_cgroup_limit(&t))
        .min()
}

/// A cgroup memory limit file's value: bytes, or `None` for `max` (v2) or a
/// value of 2⁶² or more (v1's "unlimited" is near 2⁶³).
fn parse_cgroup_limit(text: &str) -> Option<u64> {
    let v = text.trim().parse::<u64>().ok()?;
    (v < 1 << 62).then_some(v)
}

/// The soft "Max address space" limit in `/proc/self/limits`, in bytes;
/// `None` when unlimited or absent.
fn parse_address_space_limit(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("Max address space"))?;
    let soft = line["Max address space".len()..]
        .split_whitespace()
        .next()?;
    soft.parse::<u64>().ok()
}

/// A `NAME:  1234 kB` field of `/proc/meminfo` or `/proc/self/status`, in bytes.
fn parse_kib_field(text: &str, name: &str) -> Option<u64> {
    let rest = text.lines().find_map(|l| l.strip_prefix(name))?;
    let kib = rest.split_whitespace().next()?.parse::<u64>().ok()?;
    kib.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proc_files_parse() {
        let limits = "Limit                     Soft Limit           Hard Limit           Units     \n\
                      Max cpu time              unlimited            unlimited            seconds   \n\
                      Max address space         4294967296           unlimited            bytes     \n";
        assert_eq!(parse_address_space_limit(limits), Some(4 << 30));
        let unlimited = limits.replace("4294967296", "unlimited ");
        assert_eq!(parse_address_space_limit(&unlimited), None);
        let meminfo = "MemTotal:       24576000 kB\nMemFree:         1000 kB\n";
        assert_eq!(
            parse_kib_field(meminfo, "MemTotal:"),
            Some(24_576_000 * 1024)
        );
        assert_eq!(parse_kib_field(meminfo, "VmSize:"), None);
        assert_eq!(parse_cgroup_limit("max\n"), None);
        assert_eq!(parse_cgroup_limit("1073741824\n"), Some(1 << 30));
        assert_eq!(parse_cgroup_limit("9223372036854771712\n"), None);
    }

    #[test]
    fn default_budget_is_positive_and_stable() {
        let b = default_memory_budget();
        assert!(b > 0);
        assert_eq!(Limits::default().max_memory, b);
    }
}
