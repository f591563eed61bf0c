//! What packing vector art will cost, estimated before anything is built,
//! and the level and contour-leaf budget that fit a memory budget when the
//! caller left them to the packer ([`QuadTree::from_vector_within`]).

use super::VECTOR_KNOBS;
use super::art::{MAX_VECTOR_LEVEL, Point, VectorArt};
use super::options::VectorOptions;
use super::pack::sweep::SWEEP_EDGES;
use crate::Error;
use crate::memory::{BUILD_BYTES_PER_NODE, CONTOUR_BYTES_PER_LEAF, CONTOUR_BYTES_PER_POINT};
use crate::tree::QuadTree;
use crate::vector::blend::BlendMode;
use crate::vector::contour_leaf::MAX_LEAF_GROUP_DEPTH;
use crate::vector::options::VectorReport;

/// Peak bytes per point of the art the packer holds while it clips the
/// art to the squares being built (the whole art at the root, a quarter
/// of it a level down, each list with its slack); measured as
/// [`CONTOUR_BYTES_PER_POINT`] (28 on the tiger).
const CLIP_BYTES_PER_ART_POINT: u64 = 32;

/// The lowest max level [`QuadTree::from_vector_within`] lowers a level
/// to (`256²` effective): below it, art that does not fit is refused
/// rather than packed too coarse to use.
pub const MIN_FITTED_LEVEL: u8 = 8;

/// The contour-leaf edge budgets tried, in order, above the caller's when
/// it is left to the packer (see [`Adjustable::contour_edges`]).
const EDGE_BUDGETS: [usize; 5] = [16, 32, 64, 128, 256];

/// Which of [`VectorOptions`]' settings [`QuadTree::from_vector_within`]
/// may change to fit the memory budget: those the caller left at their
/// defaults. A setting the user gave is kept, and art that does not fit
/// with it is refused with [`Error::MemoryBudget`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Adjustable {
    /// The max level may be lowered (the deepest level that fits is taken).
    pub max_level: bool,
    /// The contour-leaf edge budget may be raised, up to 256 edges (fewer,
    /// larger leaves hold fewer points: their contours are clipped fewer
    /// times; each query then sweeps more edges). Contour leaves stay
    /// exact at any magnification whatever the budget.
    pub contour_edges: bool,
}

impl Adjustable {
    /// Nothing may change: as [`QuadTree::from_vector`].
    pub const NONE: Adjustable = Adjustable {
        max_level: false,
        contour_edges: false,
    };
}

/// What [`QuadTree::from_vector_within`] packed with, and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BudgetFit {
    /// The max level packed at.
    pub max_level: u8,
    /// The contour-leaf edge budget packed with (`None`: no contour leaves).
    pub contour_leaves: Option<usize>,
    /// The estimated peak bytes at those settings
    /// ([`VectorArt::estimate_bytes`]); `None` when there was no budget
    /// (nothing was estimated).
    pub estimate: Option<u64>,
    /// The memory budget ([`VectorOptions::max_bytes`]).
    pub budget: Option<u64>,
    /// The settings asked for, when they did not fit and were changed:
    /// `(max level, contour-leaf budget, estimated peak bytes)`.
    pub asked: Option<(u8, Option<usize>, u64)>,
}

impl BudgetFit {
    /// True when the settings asked for were changed to fit the budget.
    pub fn changed(&self) -> bool {
        self.asked.is_some()
    }
}

/// Per level of a simulated contour-leaf subdivision.
#[derive(Debug, Clone, Copy, Default)]
struct Tally {
    /// Squares split.
    splits: u64,
    /// Squares kept as contour leaves (at most the budget's edges), and
    /// their edges, were this level above the max level.
    leaves: u64,
    leaf_points: u64,
    /// The same, were this level the max level (up to
    /// `max(budget, SWEEP_EDGES)` edges; squares with more are swept to
    /// their mean and keep nothing).
    last_leaves: u64,
    last_points: u64,
}

impl VectorArt {
    /// True when shape `s` may be kept by a contour leaf: a solid fill
    /// outside clip paths and masks, in groups (if any) of plain opacity,
    /// at most [`MAX_LEAF_GROUP_DEPTH`] deep.
    pub(super) fn is_plain_shape(&self, s: usize) -> bool {
        let shape = &self.shapes[s];
        let plain_group = |&g: &u32| {
            self.group_blend[g as usize] == BlendMode::Normal
                && self.group_masks[g as usize].is_empty()
        };
        shape.gradient.is_none()
            && shape.groups.len() <= MAX_LEAF_GROUP_DEPTH
            && shape.groups.iter().all(plain_group)
            && shape.clip.is_none()
            && !shape.member
            && shape.mask_of.is_none()
    }

    /// The estimated peak bytes [`QuadTree::from_vector`] holds beyond the
    /// art itself with `options`' max level and contour leaves: see
    /// [`VectorArt::estimate_bytes_per_level`].
    pub fn estimate_bytes(&self, options: &VectorOptions) -> u64 {
        let level = options.max_level.min(MAX_VECTOR_LEVEL);
        self.estimate_bytes_per_level(level, options.contour_leaves, None)[usize::from(level)]
    }

    /// The estimated peak bytes [`QuadTree::from_vector`] holds beyond the
    /// art itself, for each max level from 0 to `max_level` (entry `L`
    /// packs at max level `L`), with contour leaves of at most
    /// `contour_leaves` edges or none.
    ///
    /// Without contour leaves, or when some shape cannot be kept by one
    /// (gradients, images, clip paths, masks, blend modes), it is
    /// [`VectorArt::estimate_build_bytes`]: every square an edge crosses
    /// splits. With contour leaves over flat art, squares split only while
    /// they hold more edges than the budget, so the subdivision is
    /// simulated on the art's edges (each edge handed to the squares it
    /// crosses, a square's edges counted with two more for each run of a
    /// contour through it, the runs along its border that clipping adds):
    /// [`BUILD_BYTES_PER_NODE`] a node, [`CONTOUR_BYTES_PER_POINT`] a
    /// point and [`CONTOUR_BYTES_PER_LEAF`] a leaf of the contour leaves,
    /// and 32 bytes a point of the art for clipping it to the squares.
    /// Its cost is about the art's points times the levels where squares
    /// still split, and its memory 8 bytes per edge in a square that
    /// splits. It is an estimate, not a bound: it ignores shapes hidden
    /// under opaque ones (which only makes it larger: twice the nodes and
    /// points built on a test of overlapping opaque petals) and counts a
    /// square's edges as described (measured on the Ghostscript tiger at
    /// edge budgets 16 to 256 and levels 12 to 20: from 0.5% below to 19%
    /// above the packer's peak allocation; a few MiB below it on small
    /// art; see `docs/limits.md`).
    ///
    /// `cap`: when the simulation's edge lists would take more than `cap`
    /// bytes, it stops there, so the estimate itself never holds more
    /// than about `cap`, and the levels it did not reach get a lower bound
    /// above `cap` (the nodes and points counted so far, at least
    /// `cap + 1`): packing there would hold at least as many points as the
    /// lists hold edges, at more bytes each.
    pub fn estimate_bytes_per_level(
        &self,
        max_level: u8,
        contour_leaves: Option<usize>,
        cap: Option<u64>,
    ) -> Vec<u64> {
        let max_level = max_level.min(MAX_VECTOR_LEVEL);
        let classic = || {
            let mut sum = 0u64;
            self.estimate_level_nodes(max_level)
                .iter()
                .map(|&n| {
                    sum = sum.saturating_add(n);
                    sum.saturating_mul(BUILD_BYTES_PER_NODE)
                })
                .collect()
        };
        let Some(budget) = contour_leaves else {
            return classic();
        };
        if !(0..self.shapes.len()).all(|s| self.is_plain_shape(s)) {
            return classic();
        }
        let (tallies, stopped) = self.contour_tallies(max_level, budget, cap);
        let mut out = Vec::with_capacity(usize::from(max_level) + 1);
        let clipping = (self.points as u64).saturating_mul(CLIP_BYTES_PER_ART_POINT);
        let (mut nodes, mut leaves, mut points) = (1u64, 0u64, 0u64);
        for level in 0..=usize::from(max_level) {
            let Some(t) = tallies.get(level) else {
                // Only the cap ends the tallies early.
                debug_assert!(stopped);
                let known = nodes
                    .saturating_mul(BUILD_BYTES_PER_NODE)
                    .saturating_add(clipping)
                    .saturating_add(points.saturating_mul(CONTOUR_BYTES_PER_POINT))
                    .saturating_add(leaves.saturating_mul(CONTOUR_BYTES_PER_LEAF));
                out.push(known.max(cap.unwrap_or(0).saturating_add(1)));
                continue;
            };
            let bytes = nodes
                .saturating_mul(BUILD_BYTES_PER_NODE)
                .saturating_add(clipping)
                .saturating_add(
                    points
                        .saturating_add(t.last_points)
                        .saturating_mul(CONTOUR_BYTES_PER_POINT),
                )
                .saturating_add(
                    leaves
                        .saturating_add(t.last_leaves)
                        .saturating_mul(CONTOUR_BYTES_PER_LEAF),
                );
            out.push(bytes);
            nodes = nodes.saturating_add(t.splits.saturating_mul(4));
            leaves = leaves.saturating_add(t.leaves);
            points = points.saturating_add(t.leaf_points);
        }
        out
    }

    /// The contour-leaf subdivision simulated on the art's edges, one
    /// [`Tally`] per level from 0 to `max_level`; fewer, and `true`, when
    /// the edges handed to the next level would take more than `cap`
    /// bytes (8 each, in two lists).
    fn contour_tallies(
        &self,
        max_level: u8,
        budget: usize,
        cap: Option<u64>,
    ) -> (Vec<Tally>, bool) {
        let contours: Vec<&[Point]> = self
            .shapes
            .iter()
            .flat_map(|s| &s.contours)
            .filter(|c| {
                let b = c.bounds;
                !(b[2] < 0.0 || b[0] > 1.0 || b[3] < 0.0 || b[1] > 1.0) && c.points.len() >= 2
            })
            .map(|c| c.points.as_slice())
            .collect();
        let max_edges = cap.map_or(usize::MAX, |c| {
            usize::try_from(c / 16).unwrap_or(usize::MAX)
        });
        // The edges in each square of the level, `(contour, edge)` in
        // order, and the squares: `(ix, iz, edges)`.
        let mut edges: Vec<(u32, u32)> = Vec::new();
        for (c, pts) in contours.iter().enumerate() {
            for e in 0..pts.len() {
                if crosses(segment(pts, e), [0.0, 0.0, 1.0, 1.0]) {
                    if edges.len() >= max_edges || edges.try_reserve(1).is_err() {
                        return (Vec::new(), true);
                    }
                    edges.push((c as u32, e as u32));
                }
            }
        }
        let mut squares: Vec<(u32, u32, std::ops::Range<usize>)> = Vec::new();
        if !edges.is_empty() {
            squares.push((0, 0, 0..edges.len()));
        }
        let last_budget = budget.max(SWEEP_EDGES) as u64;
        let mut tallies = Vec::with_capacity(usize::from(max_level) + 1);
        let (mut next_edges, mut next_squares) = (Vec::new(), Vec::new());
        for level in 0..=max_level {
            let mut t = Tally::default();
            let mut split = Vec::new();
            for (k, (_, _, range)) in squares.iter().enumerate() {
                let count = edge_count(&edges[range.clone()], &contours);
                if count <= last_budget {
                    t.last_leaves += 1;
                    t.last_points += count;
                }
                if count <= budget as u64 {
                    t.leaves += 1;
                    t.leaf_points += count;
                } else if level < max_level {
                    t.splits += 1;
                    split.push(k);
                }
            }
            tallies.push(t);
            if level == max_level || split.is_empty() {
                break;
            }
            next_edges.clear();
            next_squares.clear();
            let side = (-f64::from(level + 1)).exp2();
            for k in split {
                let (ix, iz, range) = &squares[k];
                for child in 0..4u32 {
                    let (cx, cz) = (2 * ix + (child & 1), 2 * iz + (child >> 1));
                    let (x0, z0) = (f64::from(cx) * side, f64::from(cz) * side);
                    let rect = [x0, z0, x0 + side, z0 + side];
                    let start = next_edges.len();
                    for &(c, e) in &edges[range.clone()] {
                        if crosses(segment(contours[c as usize], e as usize), rect) {
                            if next_edges.len() >= max_edges || next_edges.try_reserve(1).is_err() {
                                return (tallies, true);
                            }
                            next_edges.push((c, e));
                        }
                    }
                    if next_edges.len() > start {
                        next_squares.push((cx, cz, start..next_edges.len()));
                    }
                }
            }
            std::mem::swap(&mut edges, &mut next_edges);
            std::mem::swap(&mut squares, &mut next_squares);
        }
        // Below the last split every level holds no square.
        tallies.resize(usize::from(max_level) + 1, Tally::default());
        (tallies, false)
    }
}

/// Edge `e` of closed contour `pts`.
fn segment(pts: &[Point], e: usize) -> [Point; 2] {
    [pts[e], pts[(e + 1) % pts.len()]]
}

/// True when segment `s` meets the closed rectangle `[x0, z0, x1, z1]`.
fn crosses(s: [Point; 2], r: [f64; 4]) -> bool {
    let [a, b] = s;
    if a[0].max(b[0]) < r[0]
        || a[0].min(b[0]) > r[2]
        || a[1].max(b[1]) < r[1]
        || a[1].min(b[1]) > r[3]
    {
        return false;
    }
    // The rectangle's corners all on one side of the line: it misses.
    let (dx, dz) = (b[0] - a[0], b[1] - a[1]);
    let side = |x: f64, z: f64| dx * (z - a[1]) - dz * (x - a[0]);
    let s = [
        side(r[0], r[1]),
        side(r[2], r[1]),
        side(r[2], r[3]),
        side(r[0], r[3]),
    ];
    !(s.iter().all(|&v| v > 0.0) || s.iter().all(|&v| v < 0.0))
}

/// The edges a square's clipped contours are estimated to hold, given the
/// `(contour, edge)` pairs that cross it (in order): one per edge, and two
/// per run of consecutive edges of a contour that is not the whole
/// contour (clipping closes the run along the square's border: a point
/// where it leaves, and the square's corners between; counting three
/// instead put the tiger's estimate 20–30% above the packer's peak, two
/// puts it within −0.5% and +19%, and a grid of coarse 2000-gons 12% below).
fn edge_count(edges: &[(u32, u32)], contours: &[&[Point]]) -> u64 {
    let mut count = edges.len() as u64;
    let mut k = 0;
    while k < edges.len() {
        let (c, first) = edges[k];
        let mut end = k + 1;
        while end < edges.len() && edges[end] == (c, edges[end - 1].1 + 1) {
            end += 1;
        }
        let whole = first == 0 && end - k == contours[c as usize].len();
        if !whole {
            count += 2;
        }
        k = end;
    }
    count
}

impl VectorArt {
    /// [`VectorArt::estimate_bytes_per_level`] with `budget` as the cap.
    fn estimates_under(
        &self,
        max_level: u8,
        contour_leaves: Option<usize>,
        budget: u64,
    ) -> Vec<u64> {
        self.estimate_bytes_per_level(max_level, contour_leaves, Some(budget))
    }

    /// Refuses `options` when their estimate ([`VectorArt::estimate_bytes`])
    /// is above their budget, as [`QuadTree::from_vector`] does.
    pub(super) fn check_estimate(&self, options: &VectorOptions) -> Result<Option<u64>, Error> {
        let Some(budget) = options.max_bytes else {
            return Ok(None);
        };
        let level = options.max_level.min(MAX_VECTOR_LEVEL);
        let estimate =
            self.estimates_under(level, options.contour_leaves, budget)[usize::from(level)];
        if estimate > budget {
            return Err(Error::MemoryBudget {
                what: format!("packing at level {level}"),
                estimate,
                budget,
                knobs: VECTOR_KNOBS,
            });
        }
        Ok(Some(estimate))
    }

    /// The settings [`QuadTree::from_vector_within`] packs with:
    /// `options`' own when their estimate ([`VectorArt::estimate_bytes`])
    /// is within their memory budget (or there is none); otherwise, of the
    /// settings `adjustable` lets change, the deepest max level that fits
    /// (not below [`MIN_FITTED_LEVEL`]), and at it the fewest contour-leaf
    /// edges (the options' budget, then 32, 64, 128 and 256). [`Error::MemoryBudget`] when nothing fits,
    /// naming the estimate of the settings asked for.
    pub fn fit_budget(
        &self,
        options: &VectorOptions,
        adjustable: Adjustable,
    ) -> Result<BudgetFit, Error> {
        let level = options.max_level.min(MAX_VECTOR_LEVEL);
        let mut fit = BudgetFit {
            max_level: level,
            contour_leaves: options.contour_leaves,
            estimate: None,
            budget: options.max_bytes,
            asked: None,
        };
        let Some(budget) = options.max_bytes else {
            return Ok(fit);
        };
        if !(adjustable.max_level || adjustable.contour_edges) {
            fit.estimate = self.check_estimate(options)?;
            return Ok(fit);
        }
        let asked = self.estimates_under(level, options.contour_leaves, budget);
        let asked_estimate = asked[usize::from(level)];
        fit.estimate = Some(asked_estimate);
        if asked_estimate <= budget {
            return Ok(fit);
        }
        let mut tries = vec![(options.contour_leaves, asked)];
        if let Some(edges) = options.contour_leaves
            && adjustable.contour_edges
        {
            for more in EDGE_BUDGETS.into_iter().filter(|&e| e > edges) {
                let bytes = self.estimates_under(level, Some(more), budget);
                tries.push((Some(more), bytes));
            }
        }
        let lowest = if adjustable.max_level {
            level.min(MIN_FITTED_LEVEL)
        } else {
            level
        };
        for l in (lowest..=level).rev() {
            for (edges, bytes) in &tries {
                let estimate = bytes[usize::from(l)];
                if estimate <= budget {
                    return Ok(BudgetFit {
                        max_level: l,
                        contour_leaves: *edges,
                        estimate: Some(estimate),
                        budget: Some(budget),
                        asked: Some((level, options.contour_leaves, asked_estimate)),
                    });
                }
            }
        }
        let mut what = format!("packing at level {level}");
        let more_edges = if tries.len() > 1 {
            ", with contour leaves of up to 256 edges"
        } else {
            ""
        };
        if lowest < level {
            what += &format!(" (and at every level down to {lowest}{more_edges})");
        } else if !more_edges.is_empty() {
            what += &format!(" (also{more_edges})");
        }
        Err(Error::MemoryBudget {
            what,
            estimate: asked_estimate,
            budget,
            knobs: "raise --memory-limit",
        })
    }
}

impl QuadTree {
    /// Packs vector art as [`QuadTree::from_vector`] does, but where
    /// `options` do not fit their memory budget
    /// ([`VectorOptions::max_bytes`]), first changes the settings
    /// `adjustable` allows (those the caller left at their defaults) to the
    /// deepest level and fewest contour-leaf edges whose estimate fits
    /// ([`VectorArt::fit_budget`]); returns what it packed with, to be said
    /// to the user. Settings the caller gave are kept, and art that does
    /// not fit with them is refused with [`Error::MemoryBudget`].
    pub fn from_vector_within(
        art: &VectorArt,
        options: &VectorOptions,
        adjustable: Adjustable,
    ) -> Result<(QuadTree, VectorReport, BudgetFit), Error> {
        super::pack::check_options(options)?;
        let fit = art.fit_budget(options, adjustable)?;
        let fitted = VectorOptions {
            max_level: fit.max_level,
            contour_leaves: fit.contour_leaves,
            ..*options
        };
        let (tree, report) = super::pack::build(art, &fitted)?;
        Ok((tree, report, fit))
    }
}
