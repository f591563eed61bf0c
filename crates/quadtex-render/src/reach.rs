//! Where on the screen a frame's mesh triangles may reach ([`MeshReach`]):
//! the visibility pass marks it, the exact pixel's search of the meshes
//! consults it.

/// Side of [`MeshReach`]'s tiles, in pixels.
const REACH_TILE: f64 = 8.0;

/// Slack (pixels) around a triangle's projected corners when its tiles are
/// marked: the projection here and a view's lines round differently, by
/// many orders of magnitude less.
const REACH_SLACK: f64 = 1.0;

/// Where on the screen a frame's mesh triangles may reach: tiles of
/// [`REACH_TILE`] pixels over the padded grid, each marked when the screen
/// box of some triangle's projected corners (plus [`REACH_SLACK`]) touches
/// it; everywhere when a triangle reaches behind the camera's plane. A
/// triangle with its corners in front projects inside their box, so a
/// screen box that touches no marked tile meets no triangle: the search of
/// the meshes' hierarchies for one ([`crate::exact::SurfaceViews::meshes_in`]) is
/// skipped, exactly. Below the horizon of a terrain every tile is marked;
/// the sky above it is not.
#[derive(Debug, Clone)]
pub(crate) struct MeshReach {
    /// Screen coordinate of the tiles' top-left corner (`−pad`, both axes).
    origin: f64,
    /// Tiles across and down.
    tiles: [usize; 2],
    marked: Vec<bool>,
    everywhere: bool,
}

impl MeshReach {
    pub(crate) fn new((gw, gh): (usize, usize), pad: f64) -> MeshReach {
        let tiles = [gw, gh].map(|n| (n as f64 / REACH_TILE).ceil() as usize);
        MeshReach {
            origin: -pad,
            tiles,
            marked: vec![false; tiles[0] * tiles[1]],
            everywhere: false,
        }
    }

    /// Reach everywhere: nothing is ruled out.
    pub(crate) fn everywhere() -> MeshReach {
        MeshReach {
            origin: 0.0,
            tiles: [0, 0],
            marked: Vec::new(),
            everywhere: true,
        }
    }

    /// The tiles `[first, last]` along `axis` that screen interval
    /// `[lo, hi]` touches, clamped to the grid, or `Err(())` when it
    /// reaches past the grid's edge (or is not a number); `Ok(None)` when
    /// it lies wholly beyond.
    fn span(&self, axis: usize, lo: f64, hi: f64) -> Result<Option<(usize, usize)>, ()> {
        let n = self.tiles[axis] as f64;
        let (a, b) = (
            ((lo - self.origin) / REACH_TILE).floor(),
            ((hi - self.origin) / REACH_TILE).floor(),
        );
        if a.is_nan() || b.is_nan() {
            return Err(());
        }
        if b < 0.0 || a >= n {
            return Ok(None);
        }
        if a < 0.0 || b >= n {
            return Err(());
        }
        Ok(Some((a as usize, b as usize)))
    }

    /// Marks the tiles the screen box `[lo, hi]` touches, with
    /// [`REACH_SLACK`]; a box past the grid's edge marks what it touches
    /// of the grid, a box not a number marks everything.
    pub(crate) fn mark(&mut self, lo: [f64; 2], hi: [f64; 2]) {
        let clamp = |axis: usize, v: f64| {
            let end = self.origin + self.tiles[axis] as f64 * REACH_TILE;
            v.clamp(self.origin - REACH_TILE, end + REACH_TILE)
        };
        let mut ranges = [(0, 0); 2];
        for axis in 0..2 {
            let (a, b) = (lo[axis] - REACH_SLACK, hi[axis] + REACH_SLACK);
            if a.is_nan() || b.is_nan() {
                self.everywhere = true;
                return;
            }
            let (a, b) = (clamp(axis, a), clamp(axis, b));
            let last = self.tiles[axis] as f64 - 1.0;
            let (a, b) = (
                ((a - self.origin) / REACH_TILE).floor().max(0.0),
                ((b - self.origin) / REACH_TILE).floor().min(last),
            );
            if a > b {
                return;
            }
            ranges[axis] = (a as usize, b as usize);
        }
        for ty in ranges[1].0..=ranges[1].1 {
            let row = ty * self.tiles[0];
            self.marked[row + ranges[0].0..=row + ranges[0].1].fill(true);
        }
    }

    /// Marks everything (a triangle whose reach is unknown).
    pub(crate) fn mark_everywhere(&mut self) {
        self.everywhere = true;
    }

    /// Whether a mesh triangle may reach into the screen box `[lo, hi]`:
    /// false only when the box lies within the grid and touches no marked
    /// tile.
    pub(crate) fn may_reach(&self, lo: [f64; 2], hi: [f64; 2]) -> bool {
        if self.everywhere {
            return true;
        }
        let (Ok(x), Ok(y)) = (self.span(0, lo[0], hi[0]), self.span(1, lo[1], hi[1])) else {
            return true;
        };
        let (Some((x0, x1)), Some((y0, y1))) = (x, y) else {
            return false;
        };
        (y0..=y1).any(|ty| {
            self.marked[ty * self.tiles[0] + x0..=ty * self.tiles[0] + x1].contains(&true)
        })
    }
}
