//! The walk over tiles and squares: refining the parts of the texture
//! plane a region covers, largest error first, within a budget.

use crate::colour::WeightedColour;
use crate::filter::options::FilterStats;
use crate::filter::pixel_filter::PixelFilter;
use crate::filter::projection::{Mat3, adjugate, apply};
use crate::filter::query::{RegionIntegral, RegionQuery};
use crate::filter::scan::scan_grid;
use crate::filter::tiles::{
    Class, Line, MAX_EDGES, Segment, TileFrame, classify, edges_of, one_run_of_tiles, segments,
    tile_map,
};
use crate::filter::wrap::{Wrap, WrapMode};
use crate::geometry::polygon::{ConvexPolygon, bounds_of};
use crate::tree::{NodeRef, QuadTree, unit_side};

/// Whole-tile blocks of more tiles than this are taken at the tile mean
/// whatever their bound (reported): descending into that many trees costs
/// more than it is worth.
pub(super) const MAX_TILES_DESCENDED: f64 = 16.0;

/// Most cells of the grid at the tree's depth [`Walk::scan_texels`] takes
/// a region's part of a tile over, texel by texel, instead of walking it.
pub(super) const TEXEL_SCAN_CELLS: f64 = 256.0;

/// [`Walk::scan_texels`] scans below a node at most this many levels above
/// the texel blocks: a region within 4 × 4 blocks (16 × 16 texels of
/// 4-texel blocks). Measured with 256 cells, `quadtex render` of the
/// terrain at 480×270: its texture integrals 6.02 → 3.68 G instructions.
/// Scanning below any node was faster still there, but the demo at
/// 960×540 took 4.46 G instructions against 4.31 G with this limit (its
/// runway's uniform squares taken cell by cell instead of whole).
pub(super) const TEXEL_SCAN_LEVELS_ABOVE_BLOCKS: u8 = 2;

/// The walk starts below the root ([`Walk::start_node`]) only for error
/// bounds below this fraction of full contrast: above it, a square holding
/// the whole region might be taken whole.
pub(super) const MAX_SKIPPED_EPSILON: f64 = 0.5;

/// How far (tree units) a region's bounds must keep from a square's middle
/// lines for [`Walk::start_node`] to place it in one half: many times the
/// rounding of a tile frame's edges (a few ulps of the tile index).
pub(super) const START_MARGIN: f64 = 1e-9;

/// A refinement over more than [`MAX_TILES_DESCENDED`] tiles that the
/// budget stops with its bound above this fraction of full contrast is
/// replaced by the coarse sum (see `Walk::run`).
pub(super) const UNCONTROLLED: f64 = 0.05;

/// Squares a whole tile is reckoned to cost when a block of them is
/// descended into ([`Walk::evaluate_block`]'s promise under no budget).
const SQUARES_PER_TILE: f64 = 4.0;

/// A region over more than [`MAX_TILES_DESCENDED`] tiles whose perimeter
/// (in tiles) is more than this many times the budget of squares, and
/// whose coarse bound is its whole weight, takes the coarse sum without
/// refining (see `Walk::run`): a boundary that long crosses more tiles
/// than the budget can evaluate.
pub(super) const BOUNDARY_TILES_PER_SQUARE: f64 = 2.0;

/// The growable parts of a [`Walk`], kept per thread between regions so
/// that a walk allocates nothing once they have grown (a pixel's regions
/// are many and small).
#[derive(Default)]
pub(super) struct WalkBuffers {
    frames: Vec<TileFrame>,
    pending: Vec<Pending>,
    queue: std::collections::BinaryHeap<(u64, u32)>,
}

thread_local! {
    static WALK_BUFFERS: std::cell::RefCell<WalkBuffers> =
        std::cell::RefCell::new(WalkBuffers::default());
}

impl WalkBuffers {
    /// Parts longer than this are dropped rather than kept (a walk under a
    /// fixed level may hold [`FIXED_LEVEL_CAP`] of them).
    const KEEP: usize = 1 << 12;

    /// This thread's buffers, empty (new ones if they are lent already).
    fn lend() -> WalkBuffers {
        WALK_BUFFERS
            .try_with(|b| b.try_borrow_mut().map(|mut b| std::mem::take(&mut *b)))
            .ok()
            .and_then(Result::ok)
            .unwrap_or_default()
    }

    /// Returns the buffers, emptied, for the thread's next walk.
    fn give_back(mut self) {
        if self.frames.capacity() > Self::KEEP
            || self.pending.capacity() > Self::KEEP
            || self.queue.capacity() > Self::KEEP
        {
            return;
        }
        self.frames.clear();
        self.pending.clear();
        self.queue.clear();
        let _ = WALK_BUFFERS.try_with(|b| {
            if let Ok(mut b) = b.try_borrow_mut() {
                *b = self;
            }
        });
    }
}

/// What [`walk_region`] needs of a region beyond its [`RegionQuery`].
pub(super) struct WalkPlan {
    /// The region in texture space.
    pub(super) texture_region: ConvexPolygon,
    /// Its texture-space bounding box, `(lo, hi)`.
    pub(super) texture_box: ([f64; 2], [f64; 2]),
    /// The region's screen area and perimeter.
    pub(super) area: f64,
    pub(super) perimeter: f64,
    /// The level every square descends to, under a fixed level of detail.
    pub(super) fixed: Option<u8>,
    /// The error bound aimed at (0 under a fixed level).
    pub(super) epsilon: f64,
    /// What `epsilon` is relative to: the region's share of its pixel's
    /// weight (`PixelFilter::weight_scale`).
    pub(super) weight_scale: f64,
    /// Whether [`Walk::scan_texels`] may take tiles texel by texel.
    pub(super) texel_scan: bool,
}

/// The walk over the region's tiles and squares, adding to `out` (what
/// the horizon's sliver gave), with the buffers this thread keeps.
pub(super) fn walk_region(
    query: &RegionQuery<'_>,
    plan: WalkPlan,
    out: RegionIntegral,
    stats: &mut FilterStats,
) -> RegionIntegral {
    let (tree, projection, filter) = (query.tree, query.projection, query.filter);
    let WalkPlan {
        texture_region,
        texture_box: (lo, hi),
        area,
        perimeter,
        fixed,
        epsilon,
        weight_scale,
        texel_scan,
    } = plan;
    let buffers = WalkBuffers::lend();
    let mut walk = Walk {
        frames: buffers.frames,
        pending: buffers.pending,
        queue: buffers.queue,
        queued_bound: 0.0,
        target: epsilon * weight_scale,
        area,
        // The cap is hard: a larger budget stops there too.
        budget: query
            .options
            .budget()
            .map_or(FIXED_LEVEL_CAP, |b| b.min(FIXED_LEVEL_CAP)),
        tree,
        wrap: query.wrap,
        filter,
        centre: query.centre,
        screen_from_texture: projection.screen_from_texture,
        screen_det: adjugate(&projection.screen_from_texture).1.abs(),
        edges: edges_of(&texture_region),
        region: texture_region,
        fixed,
        boundary_coef: 0.5 * epsilon * weight_scale / perimeter.max(f64::MIN_POSITIVE),
        k_max: filter.k_max(),
        lipschitz: filter.lipschitz(),
        bound_scale: query.bound_scale,
        out,
        visited: 0,
        texel_scan,
        edge_means: [None; 4],
    };
    // The walk's bounds assume colour channels in [0, 1]; HDR colours, and
    // a border colour outside the tree's range, span more. What the
    // horizon's sliver gave (in colour units) joins them in their units,
    // so that the walk weighs it against the target as it does its own.
    let scale = query.bound_scale;
    walk.out.error_bound /= scale;
    walk.run(lo, hi);
    stats.traversal.nodes_visited += walk.visited;
    walk.out.error_bound *= scale;
    let out = walk.out;
    WalkBuffers {
        frames: walk.frames,
        pending: walk.pending,
        queue: walk.queue,
    }
    .give_back();
    out
}

/// Most squares a region evaluates under a fixed level
/// ([`crate::LevelOfDetail::Fixed`]), or under an error bound with no square
/// budget ([`crate::FilterOptions::default`]), before it stops refining and
/// reports its bound: about 80 MiB of pending parts at most.
pub const FIXED_LEVEL_CAP: u64 = 1 << 20;

/// One clamp stripe's edge seen from one of its tiles: the edge beyond
/// which it lies (`axis`, `high`) and how the tile's axis along the edge
/// maps to the tree ([`tile_map`]: texture = `sign·local + offset`).
#[derive(Debug, Clone, Copy)]
pub(super) struct EdgeStripe {
    axis: usize,
    high: bool,
    sign: f64,
    offset: f64,
}

/// What taking a square or block whole adds: `Σ colour·k`, `Σ k`, bound.
#[derive(Debug, Clone, Copy)]
pub(super) struct Contribution {
    colour: [f64; 4],
    weight: f64,
    bound: f64,
}

/// A part of the texture plane the walk may refine.
#[derive(Debug, Clone, Copy)]
pub(super) enum Item {
    /// Whole tiles `[i0, i1] × [j0, j1]`.
    Block { i0: i64, i1: i64, j0: i64, j1: i64 },
    /// Tree node `node` at `(level, ix, iz)` of tile frame `frame`.
    Node {
        frame: u32,
        node: NodeRef,
        level: u8,
        ix: u32,
        iz: u32,
    },
}

#[derive(Debug, Clone, Copy)]
pub(super) struct Pending {
    item: Item,
    taken: Contribution,
}

pub(super) enum Outcome {
    Outside,
    Final(Contribution),
    /// What taking it whole adds, and the item to refine it from.
    Refinable(Contribution, Item),
}

pub(super) struct Walk<'a> {
    frames: Vec<TileFrame>,
    pending: Vec<Pending>,
    /// `(bound bits, index into pending)`: positive floats order as their bits.
    queue: std::collections::BinaryHeap<(u64, u32)>,
    queued_bound: f64,
    target: f64,
    /// The region's screen area.
    area: f64,
    budget: u64,
    tree: &'a QuadTree,
    wrap: Wrap,
    filter: PixelFilter,
    centre: [f64; 2],
    screen_from_texture: Mat3,
    /// `|det|` of `screen_from_texture`, for the density `|det| / w³`.
    screen_det: f64,
    region: ConvexPolygon,
    edges: ([Line; MAX_EDGES], usize),
    fixed: Option<u8>,
    boundary_coef: f64,
    k_max: f64,
    lipschitz: f64,
    /// [`crate::Texture::bound_scale`]: what the tree's moments, in
    /// colour units, are divided by to weigh against unit-contrast bounds.
    bound_scale: f64,
    out: RegionIntegral,
    visited: u64,
    /// Whether [`Walk::scan_texels`] may take tiles texel by texel: a
    /// square tree with texel blocks and no gradient or contour leaves
    /// (every terminal square uniform), walked to an error bound (a fixed
    /// level asks for that level's approximation).
    texel_scan: bool,
    /// Mean colour along each edge (x low, x high, z low, z high), for
    /// clamp stripes over many tiles, computed when first needed.
    edge_means: [Option<[f64; 4]>; 4],
}

impl Walk<'_> {
    fn run(&mut self, lo: [f64; 2], hi: [f64; 2]) {
        let xs = segments(self.wrap.x(), lo[0], hi[0]);
        let zs = segments(self.wrap.z(), lo[1], hi[1]);
        for zs in zs.into_iter().flatten() {
            for xs in xs.into_iter().flatten() {
                match (xs, zs) {
                    (Segment::Tiles(i0, i1), Segment::Tiles(j0, j1)) => {
                        self.offer(Item::Block { i0, i1, j0, j1 })
                    }
                    _ => self.outside(xs, zs),
                }
            }
        }
        // Over many periods of a repeated texture, a refinement the budget
        // cuts short far from its bound is biased: the parts refined first
        // (the largest, the nearest) follow the slow drift of a moiré
        // between the region's edges and the tiles, and the rest, at the
        // tile mean, does not cancel it. The coarse sum (every tile at the
        // tile mean) keeps that cancellation, so it is returned instead,
        // with its own (larger, still rigorous) bound. Measured on the
        // checker scene at 960×540, RMSE against the closed form:
        // 2.2e-3 → 6.1e-4 at the default budget.
        // The coarse sum is what was offered before refining: `out` then,
        // plus the first `offered` pending parts (pending only grows).
        // A region whose coarse sum controls none of its weight (the bound
        // of what was offered is the whole weight) and whose boundary
        // crosses more tiles than the budget has squares is not refined:
        // its boundary blocks keep their bounds until each tile along it
        // is evaluated, which the budget cannot pay for, so the refinement
        // would end cut short and the coarse sum be taken anyway. Measured
        // at 960 wide: every region of more than 16 tiles the demo (2880),
        // the runway scene (2924) and the checker scene (1922) refined went
        // to the coarse sum, each with its whole weight as the coarse bound
        // and a perimeter of 243 tiles or more; images byte-identical (those
        // and the sign and close-up scenes, 960 and 1920 wide, box, tent
        // and Mitchell), the demo's frame at 960 wide 2.82 → 2.34 G
        // instructions.
        let n_tiles = one_run_of_tiles(&xs).unwrap_or(1.0) * one_run_of_tiles(&zs).unwrap_or(1.0);
        let (before, offered) = (self.out, self.pending.len());
        let unresolvable = self.fixed.is_none()
            && n_tiles > MAX_TILES_DESCENDED
            && self.region.perimeter() > BOUNDARY_TILES_PER_SQUARE * self.budget as f64
            // The whole weight up to rounding: the pieces' areas and the
            // region's are summed over different vertices.
            && before.error_bound + self.queued_bound >= self.k_max * self.area * (1.0 - 1e-9);
        let cut_short = !unresolvable && self.refine();
        if unresolvable
            || n_tiles > MAX_TILES_DESCENDED
                && cut_short
                && self.fixed.is_none()
                && self.out.error_bound > UNCONTROLLED * self.k_max * self.area
        {
            let mut coarse = before;
            for p in &self.pending[..offered] {
                coarse.add(&RegionIntegral {
                    colour: WeightedColour(p.taken.colour),
                    weight: p.taken.weight,
                    error_bound: p.taken.bound,
                });
            }
            self.out = coarse;
        }
    }

    /// Tile `(i, j)`'s part of the region, exactly, texel by texel: when
    /// `start`, the node the walk would start from ([`Walk::start_node`]),
    /// lies at most [`TEXEL_SCAN_LEVELS_ABOVE_BLOCKS`] levels above the
    /// texel blocks, and the region's part of it spans at most
    /// [`TEXEL_SCAN_CELLS`] cells of the grid at the tree's depth, all
    /// under uniform squares (texels or stored terminal squares). `None`
    /// (nothing added) otherwise.
    ///
    /// A region of a pixel or less over a raster (a mesh's triangle, a
    /// magnified or mildly minified photograph) spans a few texels; the
    /// walk refines it square by square down to them, each square clipped,
    /// bounded and queued, where here each texel costs one cut of its band.
    fn scan_texels(
        &mut self,
        frame: usize,
        (i, j): (i64, i64),
        (node, level, ix, iz): (NodeRef, u8, u32, u32),
    ) -> Option<Contribution> {
        if !self.texel_scan {
            return None;
        }
        // Only among texel blocks: above them the tree keeps uniform
        // squares the walk takes whole, where a scan would take each cell.
        let blocks = self.tree.texel_blocks()?;
        if level + TEXEL_SCAN_LEVELS_ABOVE_BLOCKS < blocks.level() {
            return None;
        }
        // Local (tree) coordinates of a square tree: texture = sign·local
        // + offset ([`Walk::tile_frame`]), sign ±1.
        let (sx, ox) = tile_map(self.wrap.x(), i);
        let (sz, oz) = tile_map(self.wrap.z(), j);
        let side = unit_side(level);
        let (x0, z0) = (f64::from(ix) * side, f64::from(iz) * side);
        let mut local = self
            .region
            .map_counter_clockwise(|[x, z]| [(x - ox) * sx, (z - oz) * sz]);
        let (lo, hi) = local.bounds();
        if lo[0] < x0 || lo[1] < z0 || hi[0] > x0 + side || hi[1] > z0 + side {
            local = local.clip_rect(x0, z0, x0 + side, z0 + side);
        }
        let (lo, hi) = local.bounds();
        let h = unit_side(self.tree.depth());
        let span = |a: f64, b: f64| (b / h).ceil() - (a / h).floor();
        if local.is_empty() || span(lo[0], hi[0]) * span(lo[1], hi[1]) > TEXEL_SCAN_CELLS {
            return None;
        }
        let colour = finest_colour_below(self.tree, (node, level, ix, iz));
        let (colour, weight, cells) = scan_grid(
            &local,
            &self.frames[frame].to_screen,
            h,
            self.filter,
            self.centre,
            TEXEL_SCAN_CELLS,
            colour,
        )?;
        self.visited += cells as u64;
        Some(Contribution {
            colour,
            weight,
            bound: 0.0,
        })
    }

    /// Adds `colour` over the screen polygon `piece`; `approximate` pieces
    /// (a non-terminal square taken whole over part of it) add their bound.
    #[inline]
    fn add(&mut self, colour: [f64; 4], piece: &ConvexPolygon, approximate: bool) {
        let w = self.filter.integral(piece, self.centre);
        for (a, c) in self.out.colour.0.iter_mut().zip(colour) {
            *a += c * w;
        }
        self.out.weight += w;
        if approximate {
            self.out.error_bound += self.k_over(piece.vertices()) * piece.area();
        }
    }

    /// The largest `|k|` over the screen points' box: where a square's
    /// colour can be off, the filter weighs it by at most this (the box's
    /// is 1 everywhere in its support; a tent's or Mitchell's falls
    /// towards its edges, and a square there is bounded by what it weighs
    /// there, not by the peak at the centre).
    #[inline]
    fn k_over(&self, points: &[[f64; 2]]) -> f64 {
        if self.filter == PixelFilter::Box {
            return self.k_max;
        }
        self.k_in(bounds_of(points))
    }

    /// [`Walk::k_over`] a screen box (the filter's peak where the box is
    /// not finite).
    #[inline]
    fn k_in(&self, (lo, hi): ([f64; 2], [f64; 2])) -> f64 {
        if self.filter == PixelFilter::Box || !lo.iter().chain(&hi).all(|v| v.is_finite()) {
            return self.k_max;
        }
        self.filter.largest_weight_in((lo, hi), self.centre)
    }

    fn to_screen_poly(&self, p: &ConvexPolygon, m: &Mat3) -> ConvexPolygon {
        p.map(|t| apply(m, t))
    }

    /// Offers `item`: a part taken exactly is added now, one that could be
    /// refined waits in the queue with what taking it whole contributes.
    fn offer(&mut self, item: Item) {
        let outcome = self.evaluate(item);
        self.take_outcome(outcome);
    }

    /// Adds a final part, or queues a refinable one.
    fn take_outcome(&mut self, outcome: Outcome) {
        match outcome {
            Outcome::Outside => {}
            Outcome::Final(c) => self.add_contribution(&c),
            Outcome::Refinable(c, item) => {
                self.queued_bound += c.bound;
                let index = self.pending.len() as u32;
                self.pending.push(Pending { item, taken: c });
                self.queue.push((c.bound.to_bits(), index));
            }
        }
    }

    /// True once the region has evaluated its budget of squares (under a
    /// fixed level: the hard cap).
    fn over_budget(&self) -> bool {
        self.visited
            >= match self.fixed {
                None => self.budget,
                Some(_) => FIXED_LEVEL_CAP,
            }
    }

    fn add_contribution(&mut self, c: &Contribution) {
        for (a, v) in self.out.colour.0.iter_mut().zip(c.colour) {
            *a += v;
        }
        self.out.weight += c.weight;
        self.out.error_bound += c.bound;
    }

    /// Refines the queued part with the largest bound first, until the
    /// bound is met or the budget spent (under a fixed level: until nothing
    /// above that level is left), then takes what is left whole.
    /// True when the budget (or the cap) stopped it short of the bound.
    fn refine(&mut self) -> bool {
        let mut cut_short = false;
        while let Some(&(_, index)) = self.queue.peek() {
            let done = match self.fixed {
                None => {
                    let met = self.queued_bound + self.out.error_bound <= self.target;
                    cut_short = !met && self.visited >= self.budget;
                    met || cut_short
                }
                // A fixed level over a region reaching the horizon (or a
                // million tiles) would never finish: stop at a hard cap and
                // report the bound reached.
                Some(_) => self.visited >= FIXED_LEVEL_CAP,
            };
            if done {
                break;
            }
            self.queue.pop();
            let Pending { item, taken } = self.pending[index as usize];
            self.queued_bound -= taken.bound;
            match item {
                Item::Block { i0, i1, j0, j1 } => {
                    let (mi, mj) = (i0 + (i1 - i0) / 2, j0 + (j1 - j0) / 2);
                    let xs: &[(i64, i64)] = if i1 > i0 {
                        &[(i0, mi), (mi + 1, i1)]
                    } else {
                        &[(i0, i1)]
                    };
                    let zs: &[(i64, i64)] = if j1 > j0 {
                        &[(j0, mj), (mj + 1, j1)]
                    } else {
                        &[(j0, j1)]
                    };
                    for &(a, b) in zs {
                        for &(c, d) in xs {
                            self.offer(Item::Block {
                                i0: c,
                                i1: d,
                                j0: a,
                                j1: b,
                            });
                        }
                    }
                }
                Item::Node {
                    frame,
                    node,
                    level,
                    ix,
                    iz,
                } => {
                    let weights = self.children_weights(frame as usize, level, ix, iz);
                    for c in 0..4u32 {
                        let outcome = self.evaluate_node_weighed(
                            frame as usize,
                            self.tree.child_ref(node, c as usize),
                            level + 1,
                            (2 * ix + (c & 1), 2 * iz + (c >> 1)),
                            weights.map(|w| w[c as usize]),
                        );
                        self.take_outcome(outcome);
                    }
                }
            }
        }
        while let Some((_, index)) = self.queue.pop() {
            let taken = self.pending[index as usize].taken;
            self.add_contribution(&taken);
        }
        cut_short
    }

    fn contribution(&self, colour: [f64; 4], piece: &ConvexPolygon, bound: f64) -> Contribution {
        let weight = self.filter.integral(piece, self.centre);
        Contribution {
            colour: colour.map(|c| c * weight),
            weight,
            bound,
        }
    }

    fn evaluate(&mut self, item: Item) -> Outcome {
        match item {
            Item::Block { i0, i1, j0, j1 } => self.evaluate_block(i0, i1, j0, j1),
            Item::Node {
                frame,
                node,
                level,
                ix,
                iz,
            } => self.evaluate_node(frame as usize, node, level, ix, iz),
        }
    }

    /// Tiles `[i0, i1] × [j0, j1]` (both axes tiled).
    fn evaluate_block(&mut self, i0: i64, i1: i64, j0: i64, j1: i64) -> Outcome {
        let (x0, x1) = (i0 as f64, (i1 + 1) as f64);
        let (z0, z1) = (j0 as f64, (j1 + 1) as f64);
        let class = classify(&self.edges, x0, z0, x1, z1);
        if class == Class::Outside {
            return Outcome::Outside;
        }
        if i0 == i1 && j0 == j1 {
            let frame = self.tile_frame(i0, j0);
            let start = self.start_node(i0, j0);
            if let Some(c) = self.scan_texels(frame, (i0, j0), start) {
                return Outcome::Final(c);
            }
            let (node, level, ix, iz) = start;
            return self.evaluate_node(frame, node, level, ix, iz);
        }
        self.visited += 1;
        let m = self.screen_from_texture;
        let corners = [[x0, z0], [x1, z0], [x1, z1], [x0, z1]];
        let quad = ConvexPolygon::from_trusted(&corners.map(|t| apply(&m, t)));
        let root = self.tree.mean_colour();
        let root_terminal = !self.tree.node_info(QuadTree::ROOT).0;
        let (nx, nz) = ((i1 - i0 + 1) as f64, (j1 - j0 + 1) as f64);
        match class {
            Class::Inside => {
                if root_terminal {
                    return Outcome::Final(self.contribution(root, &quad, 0.0));
                }
                let (linear, curved) = self.block_bound(&corners, nx, nz);
                let (rmin, rmax) = density_range_det(&m, self.screen_det, &corners);
                let tile = tile_diameter(&corners.map(|t| apply(&m, t)), nx, nz, rmin, rmax);
                let k = self.k_over(quad.vertices());
                let within_tiles = 0.5 * self.lipschitz * tile * quad.area();
                let bound = (k * (linear + curved) + within_tiles).min(k * quad.area());
                let c = self.contribution(root, &quad, bound);
                // In the linear regime, splitting a block does not shrink its
                // bound (module documentation); only descending into tiles
                // does, worth it for a few tiles, not for many. The filter's
                // variation within each tile (a tent's or Mitchell's) shrinks
                // only by descending too, and is the larger part where tiles
                // are large on the screen: those blocks are refined.
                // With no square budget below the cap (library calls by
                // default), the bound asked for is a promise: a block whose
                // bound is above its share of the target is descended into
                // after all, where what is left of the cap can pay for its
                // tiles (a few squares each); else it is taken whole and
                // reports its bound, as at the cap.
                let promised = self.budget >= FIXED_LEVEL_CAP
                    && nx * nz * SQUARES_PER_TILE
                        <= self.budget.saturating_sub(self.visited) as f64;
                if self.fixed.is_none()
                    && nx * nz > MAX_TILES_DESCENDED
                    && curved <= linear
                    && within_tiles <= k * linear
                    && ((self.filter == PixelFilter::Box && !promised)
                        || bound <= self.target * quad.area() / self.area)
                {
                    Outcome::Final(c)
                } else {
                    Outcome::Refinable(c, Item::Block { i0, i1, j0, j1 })
                }
            }
            _ => {
                // Cut by the region's boundary: whole tiles keep the tile
                // mean (up to the covariance above); only the tiles the cut
                // crosses differ, a band one tile wide along it.
                let piece_tex = self.region.clip_rect(x0, z0, x1, z1);
                let piece = self.to_screen_poly(&piece_tex, &m);
                if root_terminal {
                    return Outcome::Final(self.contribution(root, &piece, 0.0));
                }
                let (rmin, rmax) = density_range_det(&m, self.screen_det, &corners);
                let tile = tile_diameter(&corners.map(|t| apply(&m, t)), nx, nz, rmin, rmax);
                // The tiles' screen sizes come from the block's corners: only
                // when all of them are in front of the camera. A block
                // reaching past the horizon (the region's part of it can
                // still be small) gets the whole weight as its bound.
                let in_front = corners
                    .iter()
                    .all(|t| m[2][0] * t[0] + m[2][1] * t[1] + m[2][2] > 0.0);
                let band = if in_front {
                    cut_length(&piece_tex, [x0, z0, x1, z1], &m) * tile
                } else {
                    f64::INFINITY
                };
                let (linear, curved) = self.block_bound(&corners, nx, nz);
                let k = if in_front {
                    self.k_over(piece.vertices())
                } else {
                    self.k_max
                };
                let bound = k * (band + linear + curved).min(piece.area());
                Outcome::Refinable(
                    self.contribution(root, &piece, bound),
                    Item::Block { i0, i1, j0, j1 },
                )
            }
        }
    }

    /// A bound on `|Σ_tiles Σ_leaves (c − c̄)(∫ρ − a·ρ̄)|` over a block of
    /// `nx × nz` whole tiles with texture-space `corners`: expanding `ρ` to
    /// first order about each tile's centre, the first-order terms are the
    /// tile's first moments `m` dotted with `Σ ∇ρ(centres)`, which telescopes
    /// along rows and columns to the density's range `D` across the block;
    /// the second order is the Hessian `|∂²ρ| ≤ 12ρ|∇w|²/w²` against the
    /// colour's second moments ([`QuadTree::second_moments`]), the third
    /// `|∂³ρ| ≤ 60ρ|∇w|³/w³` against its spread (`docs/algorithm.md`).
    /// Returned as the first-order part and the rest.
    fn block_bound(&self, corners: &[[f64; 2]; 4], nx: f64, nz: f64) -> (f64, f64) {
        let (m, det) = (&self.screen_from_texture, self.screen_det);
        let w_min = corners
            .iter()
            .map(|t| (m[2][0] * t[0] + m[2][1] * t[1] + m[2][2]).abs())
            .fold(f64::INFINITY, f64::min);
        let (rmin, rmax) = density_range_det(m, det, corners);
        let d = rmax - rmin;
        let g2 = m[2][0] * m[2][0] + m[2][1] * m[2][1];
        let hessian = 12.0 * rmax * g2 / (w_min * w_min);
        // The moments are in colour units; the walk's bounds are for unit
        // contrast (scaled back by the texture's contrast at its end).
        let [mx, mz] = self.tree.first_moments().map(|m| m / self.bound_scale);
        // Per tile, the second-order term: the Hessian (each entry at most
        // `hessian`, as g_x², 2|g_x g_z|, g_z² ≤ |g|²) against the colour's
        // second moments, plus the third-order remainder (|∂³ρ| ≤
        // 60ρ|∇w|³/w³, |δ| ≤ √½ from the tile's centre) against its spread;
        // without second moments, the second-order remainder against the
        // spread (|δ|² ≤ ½). Plus the moments times the Hessian for the
        // error of the telescoped sum of gradients.
        let per_tile = match self.tree.second_moments() {
            Some(moments) => {
                let [xx, xz, zz] = moments.map(|m| m / self.bound_scale);
                let third = 10.0 * rmax * g2 * g2.sqrt() / w_min.powi(3) * 0.5f64.powf(1.5);
                0.5 * hessian * (xx + xz + zz) + third
            }
            None => 0.25 * hessian,
        };
        (
            (mx * nz + mz * nx) * d,
            (mx * nz + mz * nx) * hessian + nx * nz * (per_tile + hessian * (mx + mz)),
        )
    }

    /// The frame of tile `(i, j)`: the region in the tile's local
    /// coordinates and the map from them to the screen.
    fn tile_frame(&mut self, i: i64, j: i64) -> usize {
        let (sx, ox) = tile_map(self.wrap.x(), i);
        let (sz, oz) = tile_map(self.wrap.z(), j);
        // Local coordinates are tree space: a texture of another aspect
        // spans [0, ex) × [0, ez) of it, exact powers of two.
        let aspect = self.tree.aspect();
        let [ex, ez] = aspect.scale();
        let (sx, sz) = (sx / ex, sz / ez);
        // texture = (sx·x + ox, sz·z + oz): a half-plane's line in local
        // coordinates, and the screen map composed with it.
        let mut edges = self.edges;
        for l in &mut edges.0[..edges.1] {
            *l = [l[0] * sx, l[1] * sz, l[0] * ox + l[1] * oz + l[2]];
        }
        // The pad is not texture: keep the tile to x < ex, z < ez.
        if ex < 1.0 {
            edges.0[edges.1] = [-1.0, 0.0, ex];
            edges.1 += 1;
        }
        if ez < 1.0 {
            edges.0[edges.1] = [0.0, -1.0, ez];
            edges.1 += 1;
        }
        let m = &self.screen_from_texture;
        let to_screen = [0, 1, 2].map(|r| {
            [
                m[r][0] * sx,
                m[r][1] * sz,
                m[r][0] * ox + m[r][1] * oz + m[r][2],
            ]
        });
        self.frames.push(TileFrame {
            edges,
            to_screen,
            det: self.screen_det * aspect.area_ratio(),
        });
        self.frames.len() - 1
    }

    /// Where the walk over tile `(i, j)` starts: the deepest node whose
    /// square holds the region's part of the tile strictly inside one
    /// child, down from the root through nodes of full contrast
    /// ([`QuadTree::splits_fully`]). The walk would refine each node above
    /// it first thing: its bound there is the region's whole weight (unit
    /// contrast over all of it), above any target of an error bound below
    /// [`MAX_SKIPPED_EPSILON`], and of its four children the other three
    /// miss the region. Starting below them skips evaluating four squares
    /// a level for nothing (a region of a pixel or two over a deep raster:
    /// most of the walk's squares before).
    fn start_node(&self, i: i64, j: i64) -> (NodeRef, u8, u32, u32) {
        let mut at = (QuadTree::ROOT, 0u8, 0u32, 0u32);
        if self.target >= MAX_SKIPPED_EPSILON * self.k_max * self.area {
            return at;
        }
        // The region's bounds in the tile's local (tree) coordinates:
        // texture = sign·local/extent + offset (`tile_frame`).
        let (lo, hi) = self.region.bounds();
        let extent = self.tree.aspect().scale();
        let local = |axis: usize, mode: WrapMode, tile: i64| {
            let (sign, offset) = tile_map(mode, tile);
            let a = (lo[axis] - offset) * sign * extent[axis];
            let b = (hi[axis] - offset) * sign * extent[axis];
            (a.min(b), a.max(b))
        };
        let (x, z) = (local(0, self.wrap.x(), i), local(1, self.wrap.z(), j));
        loop {
            let (node, level, ix, iz) = at;
            if self.fixed.is_some_and(|k| level >= k) || !self.tree.splits_fully(node) {
                return at;
            }
            let side = unit_side(level + 1);
            let (mx, mz) = (f64::from(2 * ix + 1) * side, f64::from(2 * iz + 1) * side);
            let (Some(hx), Some(hz)) = (half(x, mx), half(z, mz)) else {
                return at;
            };
            at = (
                self.tree.child_ref(node, (hx + 2 * hz) as usize),
                level + 1,
                2 * ix + hx,
                2 * iz + hz,
            );
        }
    }

    fn evaluate_node(&mut self, frame: usize, p: NodeRef, level: u8, ix: u32, iz: u32) -> Outcome {
        self.evaluate_node_weighed(frame, p, level, (ix, iz), None)
    }

    /// The four children's weights of square `(ix, iz)` at `level` of tile
    /// frame `frame`, when the square lies inside the region (so do they)
    /// under a tent or Mitchell filter: Green's theorem over the 3 × 3
    /// grid of their mapped corners, each of the 12 half-sides integrated
    /// once and shared by the two children beside it (16 sides otherwise).
    /// Children `c = hx + 2·hz`, as [`QuadTree::child_ref`] numbers them.
    fn children_weights(&self, frame: usize, level: u8, ix: u32, iz: u32) -> Option<[f64; 4]> {
        if self.filter == PixelFilter::Box || self.fixed.is_some_and(|k| level >= k) {
            return None;
        }
        let f = &self.frames[frame];
        let side = unit_side(level);
        let (x0, z0) = (f64::from(ix) * side, f64::from(iz) * side);
        if classify(&f.edges, x0, z0, x0 + side, z0 + side) != Class::Inside {
            return None;
        }
        let half = 0.5 * side;
        let c = self.centre;
        // `grid[j][i]`: the corner at (x0 + i·half, z0 + j·half), relative
        // to the filter's centre.
        let grid: [[[f64; 2]; 3]; 3] = std::array::from_fn(|j| {
            std::array::from_fn(|i| {
                let s = apply(&f.to_screen, [x0 + i as f64 * half, z0 + j as f64 * half]);
                [s[0] - c[0], s[1] - c[1]]
            })
        });
        let edge = |a: [f64; 2], b: [f64; 2]| self.filter.edge_integral(a, b);
        // Along x (`along[j][i]`: from corner i to i + 1 of row j) and
        // along z (`up[j][i]`: from row j to j + 1 of column i).
        let along: [[f64; 2]; 3] =
            std::array::from_fn(|j| std::array::from_fn(|i| edge(grid[j][i], grid[j][i + 1])));
        let up: [[f64; 3]; 2] =
            std::array::from_fn(|j| std::array::from_fn(|i| edge(grid[j][i], grid[j + 1][i])));
        // The corners' order (x0, z0), (x1, z0), (x1, z1), (x0, z1) turns
        // the way the whole square's does on the screen: its sign makes
        // each sum the counter-clockwise one `PixelFilter::integral` takes.
        let corners = [grid[0][0], grid[0][2], grid[2][2], grid[2][0]];
        let sign = crate::geometry::polygon::signed_area(&corners).signum();
        if sign == 0.0 || sign.is_nan() {
            return None;
        }
        let weights: [f64; 4] = std::array::from_fn(|c| {
            let (i, j) = (c & 1, c >> 1);
            sign * (along[j][i] + up[j][i + 1] - along[j + 1][i] - up[j][i])
        });
        weights.iter().all(|w| w.is_finite()).then_some(weights)
    }

    /// [`Walk::evaluate_node`], with the square's weight given where it is
    /// inside the region and already known (`weight`).
    fn evaluate_node_weighed(
        &mut self,
        frame: usize,
        p: NodeRef,
        level: u8,
        (ix, iz): (u32, u32),
        weight: Option<f64>,
    ) -> Outcome {
        let f = &self.frames[frame];
        let side = unit_side(level);
        let (x0, z0) = (f64::from(ix) * side, f64::from(iz) * side);
        let (x1, z1) = (x0 + side, z0 + side);
        let class = classify(&f.edges, x0, z0, x1, z1);
        if class == Class::Outside {
            return Outcome::Outside;
        }
        self.visited += 1;
        // `contrast` bounds the colour's deviation from the square's mean: 1
        // (full contrast) but in gradient leaves, whose range is known.
        let (inner, colour, contrast) = self.tree.node_detail(p);
        let corners = [[x0, z0], [x1, z0], [x1, z1], [x0, z1]];
        let m = f.to_screen;
        let refinable = inner && self.fixed.is_none_or(|k| level < k);
        let here = Item::Node {
            frame: frame as u32,
            node: p,
            level,
            ix,
            iz,
        };
        let piece = match class {
            Class::Inside => {
                let mapped = corners.map(|t| apply(&m, t));
                let bound = if contrast > 0.0 {
                    let (rmin, rmax) = density_range_det(&m, f.det, &corners);
                    // One box of the mapped corners for both the filter's
                    // largest weight and the square's screen diameter.
                    let screen_box = bounds_of(&mapped);
                    let diam = if self.lipschitz > 0.0 {
                        box_diagonal(screen_box)
                    } else {
                        0.0
                    };
                    0.5 * contrast
                        * side
                        * side
                        * (self.k_in(screen_box) * (rmax - rmin) + rmax * self.lipschitz * diam)
                } else {
                    0.0
                };
                // Given by the parent (shared half-sides), or the box's
                // quad's area (no polygon needed), or the filter's integral.
                let weight = match weight {
                    Some(weight) => weight,
                    None if self.filter == PixelFilter::Box => {
                        crate::geometry::polygon::signed_area(&mapped).abs()
                    }
                    None => self
                        .filter
                        .integral(&ConvexPolygon::from_trusted(&mapped), self.centre),
                };
                let c = Contribution {
                    colour: colour.map(|v| v * weight),
                    weight,
                    bound,
                };
                return if refinable && bound > 0.0 {
                    Outcome::Refinable(c, here)
                } else {
                    Outcome::Final(c)
                };
            }
            Class::Boundary(crossing) => ConvexPolygon::rect(x0, z0, x1, z1)
                .clip_lines(
                    f.edges.0[..f.edges.1]
                        .iter()
                        .enumerate()
                        .filter(|(e, _)| crossing >> e & 1 == 1)
                        .map(|(_, l)| *l),
                )
                .map(|t| apply(&m, t)),
            Class::Outside => return Outcome::Outside,
        };
        let bound = contrast * self.k_over(piece.vertices()) * piece.area();
        let c = self.contribution(colour, &piece, bound);
        if refinable {
            Outcome::Refinable(c, here)
        } else {
            Outcome::Final(c)
        }
    }

    /// A part of the plane beyond a clamp or border edge.
    fn outside(&mut self, xs: Segment, zs: Segment) {
        let range = |s: Segment| match s {
            Segment::Tiles(a, b) => (a as f64, (b + 1) as f64),
            Segment::Low => (f64::NEG_INFINITY, 0.0),
            Segment::High => (1.0, f64::INFINITY),
        };
        let (x0, x1) = range(xs);
        let (z0, z1) = range(zs);
        let piece = self.region.clip_rect(x0, z0, x1, z1);
        if piece.is_empty() {
            return;
        }
        self.visited += 1;
        let m = self.screen_from_texture;
        let x_out = !matches!(xs, Segment::Tiles(..));
        let z_out = !matches!(zs, Segment::Tiles(..));
        if (x_out && self.wrap.x() == WrapMode::Border)
            || (z_out && self.wrap.z() == WrapMode::Border)
        {
            let b = self.wrap.border_colour().to_array().map(f64::from);
            self.add(b, &self.to_screen_poly(&piece, &m), false);
            return;
        }
        if x_out && z_out {
            let c = self.corner_colour(xs == Segment::High, zs == Segment::High);
            self.add(c, &self.to_screen_poly(&piece, &m), false);
            return;
        }
        // A clamp stripe: the colour varies along the other axis only.
        let (axis, high, other) = if x_out {
            (0, xs == Segment::High, zs)
        } else {
            (1, zs == Segment::High, xs)
        };
        if let Segment::Tiles(j0, j1) = other {
            self.stripe(axis, high, j0, j1, &piece);
        }
    }

    /// Screen length of the region's boundary inside `piece`, a part of
    /// the clamp stripe beyond edge (`axis`, `high`) between `lo` and `hi`
    /// along the edge: its sides but those on the edge and on the cuts at
    /// `lo` and `hi`. Pieces taken whole when their area is at most
    /// `boundary_coef` times this share the region's perimeter, so their
    /// bounds add up to at most half the target, however far the stripe
    /// reaches across (a diameter would count that reach once a piece).
    fn stripe_cut(
        &self,
        piece: &ConvexPolygon,
        axis: usize,
        high: bool,
        (lo, hi): (f64, f64),
    ) -> f64 {
        let edge = if high { 1.0 } else { 0.0 };
        let tol = 1e-9 * (hi - lo).abs().max(1.0);
        let on = |a: f64, b: f64, c: f64| (a - c).abs() <= tol && (b - c).abs() <= tol;
        let along = 1 - axis;
        boundary_length(piece, &self.screen_from_texture, |a, b| {
            on(a[axis], b[axis], edge) || on(a[along], b[along], lo) || on(a[along], b[along], hi)
        })
    }

    /// Tiles `j0..=j1` along the stripe beyond edge (`axis`, `high`).
    fn stripe(&mut self, axis: usize, high: bool, j0: i64, j1: i64, piece: &ConvexPolygon) {
        let (b0, b1) = (j0 as f64, (j1 + 1) as f64);
        let part = clip_axis(piece, 1 - axis, b0, b1);
        if part.is_empty() {
            return;
        }
        self.visited += 1;
        let m = self.screen_from_texture;
        let screen = self.to_screen_poly(&part, &m);
        if j0 == j1 {
            let mode = if axis == 0 {
                self.wrap.z()
            } else {
                self.wrap.x()
            };
            let (sign, offset) = tile_map(mode, j0);
            let edge = EdgeStripe {
                axis,
                high,
                sign,
                offset,
            };
            self.edge_node(edge, QuadTree::ROOT, 0, 0, &part);
            return;
        }
        if self.over_budget() {
            // Out of budget: the texture's mean, the whole weight as bound.
            let c = self.tree.mean_colour();
            self.add(c, &screen, true);
            return;
        }
        if self.fixed.is_none()
            && screen.area() <= self.boundary_coef * self.stripe_cut(&part, axis, high, (b0, b1))
        {
            let c = self.edge_mean(axis, high);
            self.add(c, &screen, true);
            return;
        }
        let mid = j0 + (j1 - j0) / 2;
        self.stripe(axis, high, j0, mid, &part);
        self.stripe(axis, high, mid + 1, j1, &part);
    }

    /// The edge cells of node `p` (index `k` along the edge at `level`) over
    /// the stripe part `part` of clamp stripe `edge`.
    fn edge_node(&mut self, edge: EdgeStripe, p: NodeRef, level: u8, k: u32, part: &ConvexPolygon) {
        let EdgeStripe {
            axis,
            high,
            sign,
            offset,
        } = edge;
        // Along the edge, in texture units of that axis (tree units over the extent).
        let aspect = self.tree.aspect();
        let along = aspect.scale()[1 - axis];
        let side = unit_side(level);
        let (l0, l1) = (f64::from(k) * side / along, f64::from(k + 1) * side / along);
        if l0 >= 1.0 {
            return;
        }
        let (t0, t1) = if sign > 0.0 {
            (offset + l0, offset + l1)
        } else {
            (offset - l1, offset - l0)
        };
        let piece = clip_axis(part, 1 - axis, t0, t1);
        if piece.is_empty() {
            return;
        }
        self.visited += 1;
        let (inner, stored) = self.tree.node_info(p);
        let m = self.screen_from_texture;
        let screen = self.to_screen_poly(&piece, &m);
        let take = !inner
            || self.over_budget()
            || match self.fixed {
                Some(f) => level >= f,
                None => {
                    screen.area()
                        <= self.boundary_coef * self.stripe_cut(&piece, axis, high, (t0, t1))
                }
            };
        if take {
            self.add(stored, &screen, inner);
            return;
        }
        let h = u32::from(across_high(aspect, axis, high, level));
        for c in 0..2u32 {
            // Children on the edge: the outer half across the edge, both along it.
            let child = if axis == 0 { h + 2 * c } else { c + 2 * h };
            self.edge_node(
                edge,
                self.tree.child_ref(p, child as usize),
                level + 1,
                2 * k + c,
                &piece,
            );
        }
    }

    /// The mean colour along edge (`axis`, `high`): the stretched cells of a
    /// clamp stripe, averaged over one tile.
    fn edge_mean(&mut self, axis: usize, high: bool) -> [f64; 4] {
        let slot = 2 * axis + usize::from(high);
        if let Some(c) = self.edge_means[slot] {
            return c;
        }
        let mut acc = [0.0; 4];
        let aspect = self.tree.aspect();
        let along = aspect.scale()[1 - axis];
        let mut stack = vec![(QuadTree::ROOT, 0u8, 0u32)];
        while let Some((p, level, k)) = stack.pop() {
            let side = unit_side(level);
            let start = f64::from(k) * side;
            if start >= along {
                continue;
            }
            let (inner, c) = self.tree.node_info(p);
            if !inner {
                // Its length along the edge that is texture, in texture units.
                let length = ((start + side).min(along) - start) / along;
                for (a, v) in acc.iter_mut().zip(c) {
                    *a += v * length;
                }
                continue;
            }
            let h = usize::from(across_high(aspect, axis, high, level));
            for c in 0..2usize {
                let child = if axis == 0 { h + 2 * c } else { c + 2 * h };
                stack.push((self.tree.child_ref(p, child), level + 1, 2 * k + c as u32));
            }
        }
        self.edge_means[slot] = Some(acc);
        acc
    }

    /// The colour of the tree's corner cell (`x` high?, `z` high?).
    fn corner_colour(&self, x_high: bool, z_high: bool) -> [f64; 4] {
        let aspect = self.tree.aspect();
        let (mut p, mut level) = (QuadTree::ROOT, 0u8);
        loop {
            let (inner, colour) = self.tree.node_info(p);
            if !inner {
                return colour;
            }
            let hx = across_high(aspect, 0, x_high, level);
            let hz = across_high(aspect, 1, z_high, level);
            p = self
                .tree
                .child_ref(p, usize::from(hx) + 2 * usize::from(hz));
            level += 1;
        }
    }
}

/// Which half of a level-`level` square on the texture's edge (`axis`,
/// `high`) holds that edge: the low one for the low edge; for the high
/// edge, the half holding the texture's last cells along `axis`, the low
/// one where the extent ends in it ([`crate::Aspect`]).
#[inline]
pub(super) fn across_high(aspect: crate::Aspect, axis: usize, high: bool, level: u8) -> bool {
    high && aspect.last_index(axis, level + 1) & 1 == 1
}

/// Screen length of the edges of `piece` (a region clipped to the box
/// `[x0, z0, x1, z1]`) that are not on the box's sides: where the region's
/// boundary cuts the box.
pub(super) fn cut_length(piece: &ConvexPolygon, [x0, z0, x1, z1]: [f64; 4], m: &Mat3) -> f64 {
    let tol = 1e-9 * (x1 - x0).max(z1 - z0);
    let on = |a: f64, b: f64, c: f64| (a - c).abs() <= tol && (b - c).abs() <= tol;
    boundary_length(piece, m, |a, b| {
        on(a[0], b[0], x0) || on(a[0], b[0], x1) || on(a[1], b[1], z0) || on(a[1], b[1], z1)
    })
}

/// Screen length of the edges `(a, b)` of `piece` for which `on_side` is
/// false: the region's own boundary inside a part cut out of it.
fn boundary_length(
    piece: &ConvexPolygon,
    m: &Mat3,
    on_side: impl Fn([f64; 2], [f64; 2]) -> bool,
) -> f64 {
    let v = piece.vertices();
    let n = v.len();
    let mut total = 0.0;
    for i in 0..n {
        let (a, b) = (v[i], v[(i + 1) % n]);
        if on_side(a, b) {
            continue;
        }
        let (p, q) = (apply(m, a), apply(m, b));
        let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
        total += (dx * dx + dy * dy).sqrt();
    }
    total
}

/// The part of `p` with coordinate `axis` in `[lo, hi]`.
pub(super) fn clip_axis(p: &ConvexPolygon, axis: usize, lo: f64, hi: f64) -> ConvexPolygon {
    if axis == 0 {
        p.clip_rect(lo, f64::NEG_INFINITY, hi, f64::INFINITY)
    } else {
        p.clip_rect(f64::NEG_INFINITY, lo, f64::INFINITY, hi)
    }
}

/// A bound on the screen diameter of one tile of a block of `nx × nz`
/// tiles whose corners map to `q` on the screen (low-x low-z, high-x low-z,
/// high-x high-z, low-x high-z): the block's sides over the tile
/// counts, each axis on its own (a block one tile wide and many tall has
/// tiles as wide as itself, not a `1/max(nx, nz)` share of its diameter),
/// scaled by how much the density varies across the block.
pub(super) fn tile_diameter(q: &[[f64; 2]; 4], nx: f64, nz: f64, rmin: f64, rmax: f64) -> f64 {
    let len = |a: [f64; 2], b: [f64; 2]| length(a[0] - b[0], a[1] - b[1]);
    let along_x = len(q[1], q[0]).max(len(q[2], q[3])) / nx;
    let along_z = len(q[3], q[0]).max(len(q[2], q[1])) / nz;
    (along_x + along_z) * (rmax / rmin).max(1.0).sqrt()
}

/// `√(dx² + dy²)`, by `hypot` only where the squares overflow or
/// underflow (`hypot` costs several times more, and this runs per block).
#[inline]
pub(super) fn length(dx: f64, dy: f64) -> f64 {
    let s = (dx * dx + dy * dy).sqrt();
    if s.is_finite() && s > 1e-150 {
        s
    } else {
        dx.hypot(dy)
    }
}

/// The diagonal of the box `(lo, hi)` (of a square's mapped corners,
/// [`bounds_of`]: its screen diameter, at most).
#[inline]
pub(super) fn box_diagonal((lo, hi): ([f64; 2], [f64; 2])) -> f64 {
    let (dx, dy) = (hi[0] - lo[0], hi[1] - lo[1]);
    (dx * dx + dy * dy).sqrt()
}

/// Extremes of the screen density `|det m| / w³` over `corners`.
#[inline]
pub(super) fn density_range_det(m: &Mat3, det: f64, corners: &[[f64; 2]; 4]) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, 0f64);
    for t in corners {
        let w = (m[2][0] * t[0] + m[2][1] * t[1] + m[2][2]).abs();
        let rho = det / (w * w * w);
        lo = lo.min(rho);
        hi = hi.max(rho);
    }
    (lo, hi)
}

/// Which half of a square split at `mid` holds `(a, b)` (0 low, 1 high),
/// with room to spare for the rounding of a tile frame's edges; `None`
/// when it reaches within [`START_MARGIN`] of the middle.
#[inline]
pub(super) fn half(a_b: (f64, f64), mid: f64) -> Option<u32> {
    let (a, b) = a_b;
    if b < mid - START_MARGIN {
        Some(0)
    } else if a > mid + START_MARGIN {
        Some(1)
    } else {
        None
    }
}

/// The colour of finest cell `(x, z)` (tree space) under node `node` at
/// `(level, ix, iz)` where a uniform square holds it
/// ([`QuadTree::finest_colour`]), for [`scan_grid`].
pub(super) fn finest_colour_below(
    tree: &QuadTree,
    (node, level, ix, iz): (NodeRef, u8, u32, u32),
) -> impl Fn(i64, i64) -> Option<[f64; 4]> + '_ {
    move |x, z| {
        tree.finest_colour(
            node,
            level,
            ix,
            iz,
            u32::try_from(x).ok()?,
            u32::try_from(z).ok()?,
        )
    }
}
