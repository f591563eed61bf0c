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
    /// `[lo, hi]` touches; `None` when any of it lies past the grid's edge
    /// (where triangles are not marked) or it is not a number.
    fn span(&self, axis: usize, lo: f64, hi: f64) -> Option<(usize, usize)> {
        let n = self.tiles[axis] as f64;
        let (a, b) = (
            ((lo - self.origin) / REACH_TILE).floor(),
            ((hi - self.origin) / REACH_TILE).floor(),
        );
        // Comparisons with NaN are false: not within.
        (a >= 0.0 && b < n && a <= b).then_some((a as usize, b as usize))
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
        let (Some((x0, x1)), Some((y0, y1))) =
            (self.span(0, lo[0], hi[0]), self.span(1, lo[1], hi[1]))
        else {
            return true;
        };
        (y0..=y1).any(|ty| {
            self.marked[ty * self.tiles[0] + x0..=ty * self.tiles[0] + x1].contains(&true)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A marked box rules out only boxes a tile and its slack away; a box
    /// reaching past the grid, or not a number, is never ruled out.
    #[test]
    fn only_boxes_within_the_grid_and_away_from_marks_are_ruled_out() {
        // A 64 × 48 grid padded by 3 pixels: screen [-3, 61) × [-3, 45).
        let mut reach = MeshReach::new((64, 48), 3.0);
        reach.mark([20.0, 20.0], [21.0, 21.0]);
        // Touching the box, or within its slack and tile.
        assert!(reach.may_reach([20.5, 20.5], [20.6, 20.6]));
        assert!(reach.may_reach([21.9, 21.9], [22.5, 22.5]));
        // Far from it, inside the grid.
        assert!(!reach.may_reach([40.0, 5.0], [41.0, 6.0]));
        assert!(!reach.may_reach([-3.0, -3.0], [-2.0, -2.0]));
        // Past the grid's edge (where nothing is marked), or not a number.
        assert!(reach.may_reach([-3.5, 5.0], [-2.0, 6.0]));
        assert!(reach.may_reach([40.0, 44.0], [41.0, 46.0]));
        assert!(reach.may_reach([100.0, 100.0], [101.0, 101.0]));
        assert!(reach.may_reach([f64::NAN, 5.0], [41.0, 6.0]));
        // A box partly past the edge marks what it touches of the grid.
        reach.mark([-50.0, 30.0], [-1.0, 31.0]);
        assert!(reach.may_reach([-3.0, 30.0], [-2.0, 31.0]));
        // Not a number marks everything.
        reach.mark([f64::NAN, 0.0], [1.0, 1.0]);
        assert!(reach.may_reach([40.0, 5.0], [41.0, 6.0]));
    }
}
