//! Exact pixels: the pixel filter's support resolved in screen space into
//! the regions each primitive shows (planar ones and spheres), each
//! integrated over the texture exactly
//! ([`quadtex_core::Texture::integrate_region`]; a sphere piece by piece,
//! [`sphere`]).
//!
//! **Primitives.** Planes, quads and each mesh triangle are planar: the map
//! from screen to texture over one of them is a single projective map
//! ([`View`](crate::view::View)), exact, not a tangent-plane approximation; where it covers the
//! screen is the support clipped by a few half-planes (in front of the
//! camera; inside the quad's or triangle's edges).
//!
//! **Visibility.** The render loop records which primitive each pixel
//! centre sees. Where every centre within reach of the filter's support
//! sees the same primitive and its screen region holds the whole support,
//! the pixel is one integral. Otherwise the candidates are the primitives
//! those centres see; they are ordered front to back by comparing depths at
//! the centroid of each pair's screen overlap (planar primitives that do
//! not cross each other inside the pixel have one depth order there), and
//! the support is clipped against them in that order: each primitive gets
//! what the ones in front left. Where the listed regions leave part of the
//! support uncovered, a large mesh's triangles spread first to their
//! neighbours across the edges the support reaches past (shared corners,
//! [`crate::scene::Mesh::neighbour`]), breadth first, up to
//! [`MAX_GAP_PRIMITIVES`]: around the triangles the centres see, these
//! tile the support where the surface does not fold, and the pixel is
//! their regions, whole. Each triangle so listed is confirmed by the ray
//! through its region's centroid (or by one through the same triangle a
//! pixel or two back in the row, [`Confirmed`](views::Confirmed); such camera rays test the
//! triangles the frame's screen tiles file under their point,
//! [`crate::screen_bins`], not the meshes' hierarchies); a ray that meets
//! another primitive there (an occluder no centre sees, such as a far
//! hill's crest) undoes the spread, and that primitive joins the list
//! instead. What none of them covers is searched: the
//! ray through each gap's centroid finds the primitive there (a large
//! mesh's triangles smaller than a pixel lie between the centres), which
//! joins the list, until the gaps are sky or slivers of rounding, or
//! [`MAX_GAP_PRIMITIVES`] have joined (past that, a gap takes the colour of
//! the primitive its ray meets over all of it, its weight added to the
//! bound). A gap whose ray meets nothing is sky only once no mesh triangle
//! reaches into it: the meshes' hierarchies are searched with the gap's
//! frustum ([`SurfaceViews::meshes_in`]) and what overlaps it joins the
//! list too; a pixel whose centres in reach all see the sky is searched
//! the same way (planes and quads are always tried). Once the gaps are
//! settled, what the cut shows is searched for occluders no centre saw (a
//! far ridge's crest, thinner than a pixel, between two rows of centres):
//! every mesh triangle nearer than the farthest point the cut shows, from
//! the screen tiles over the support, that overlaps a visible region and
//! lies in front of its primitive there joins the list, and the cut takes
//! it. Overlaps of at most the sliver area (rounding along shared edges)
//! set no order, their area in the bound; where occlusion is still cyclic,
//! each primitive gets its region less those of the primitives in front of
//! it, pair by pair. A pixel whose centres in reach all see one planar
//! primitive is one integral only where no other plane, quad or mesh
//! triangle lies in front of that primitive's plane in its support and no
//! sphere's outline box meets it (tested for its run of pixels, then
//! parts of it, [`Scratch::nothing_in_front`]); one whose centres all see
//! one sphere holding its support, where nothing lies in front of the
//! sphere there (pixel by pixel). Limits, stated: primitives that
//! intersect inside the pixel are ordered at one point.
//!
//! **Shared cuts.** Runs of up to [`SHARED_CUT_PIXELS`] box pixels of a row
//! whose centres see more than one thing (and, past two, at most
//! [`SHARED_CUT_PRIMITIVES`] primitives) are cut as one support, then
//! split along the pixels' sides ([`shared_cut`]).
//! A sphere wholly in front of the camera's plane is listed like a planar
//! primitive (every sphere whose outline's box meets the support is
//! tried): its region is the support clipped by chords of its outline, its
//! depth is its near side's, and it is shaded piece by piece
//! ([`sphere`]); one reaching behind the camera's plane leaves its pixels
//! to the tangent-plane path ([`crate::pixel`]).
//!
//! **Spans.** Consecutive pixels of a row inside one primitive share one
//! texture lookup and one shadow test where the rectangle their supports
//! cover allows it ([`crate::span`]); sky pixels clear of every primitive
//! are taken from the render loop ([`Scratch::sky_pixel`]).
//!
//! **Shading.** Lambert lighting is constant over a region of a planar
//! primitive except for shadows, taken at the region's centroid. The sky's gradient over a whole
//! support (box, tent or Mitchell) is its value at the centre where a bound on that
//! rule's error is within a quarter of the filter's error bound (everywhere
//! but near the level line, [`sky_at_centre_under`](sky::sky_at_centre_under)), else 2 × 2 Gauss points;
//! over part of a pixel, the midpoint rule on quarter-pixel cells clipped to
//! the sky's part.

/// Meshes up to this many triangles have every triangle tried at a
/// silhouette pixel (larger ones: the triangles the centres see, and those
/// found in the gaps they leave).
const MAX_MESH_SCAN: usize = 256;

/// Pieces of a cut support (covered or not) of at most this fraction of
/// its area are slivers the cuts leave along shared edges (rounding): they
/// take the sky at one point, their weight as the bound, and are neither
/// cut further, integrated over a texture nor searched.
const GAP_AREA: f64 = 1e-9;

/// Most primitives a pixel adds to its list from gaps between the centres.
const MAX_GAP_PRIMITIVES: usize = 16;

mod cutting;
mod lighting;
mod occluders;
mod pixel;
mod screen_cells;

mod shared_cut;
mod sky;
mod sphere;
mod views;

#[cfg(test)]
mod tests;

pub(crate) use pixel::{Scratch, exact_pixel};
pub(crate) use shared_cut::{SHARED_CUT_PIXELS, SHARED_CUT_PRIMITIVES};
pub(crate) use sphere::PolarFans;
pub(crate) use views::SurfaceViews;
