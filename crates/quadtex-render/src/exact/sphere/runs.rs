//! Runs of pixels inside a sphere's outline that one texture square holds
//! ([`SphereView::uniform_run`]): the closed-form UV box ([`super::arcs`])
//! of the supports of several pixels of a row at once, so that the disc's
//! wide uniform stretches cost one box for a run, not one a pixel (and
//! where one texture edge crosses the run, one image of it for the run,
//! [`super::edges`]). Under
//! a light each pixel carries a light bound from the run's cosine range,
//! which holds its own ([`SphereView::light_bound`]; under the box, with
//! its own midpoint bound).

use quadtex_core::{ConvexPolygon, Rgba};

use super::super::lighting::Shading;
use super::SphereView;
use super::arcs::UvBox;
use super::edges::EdgeImage;

/// Pixels a run spans: the run's box is a little wider than one pixel's,
/// so that a checker square holds most runs a pixel's box would fit in.
const RUN: f64 = 8.0;

/// What the texture is over a run of supports ([`SphereView::uniform_run`]).
// Kept by value in a thread's `Cell` (copied out, never moved around in
// bulk): boxing the large variant would allocate once a run.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy)]
pub(super) enum RunTexture {
    /// One colour holds the run's UV box.
    One(Rgba, UvBox),
    /// One texture edge parts the run's UV box into two colours.
    Two(EdgeImage, UvBox),
    /// Neither, or the run reaches past the outline.
    Other,
}

/// The latest run a thread looked at: the view's stamp, the run's support
/// box, and what the texture is over it.
type KeptRun = (u64, ([f64; 2], [f64; 2]), RunTexture);

thread_local! {
    static LATEST_RUN: std::cell::Cell<Option<KeptRun>> = const { std::cell::Cell::new(None) };
}

impl SphereView {
    /// What the texture is over all of the support the shading's region
    /// was cut from, from the closed-form UV box (with the light's cosine)
    /// of a run of supports along the row from it (the support's box
    /// stretched [`RUN`] − 1 pixels right, lying inside the outline): one
    /// colour, or two parted by one edge ([`SphereView::edge_image`]). Kept
    /// by the thread, so the next pixels of the run find it. `None` for an
    /// untextured sphere.
    pub(super) fn uniform_run(&self, shading: &Shading<'_>) -> Option<RunTexture> {
        let texture = shading.frame.texture(self.surface)?;
        let (lo, hi) = shading.support;
        let holds = |(rlo, rhi): ([f64; 2], [f64; 2])| {
            rlo[1] == lo[1] && rhi[1] == hi[1] && rlo[0] <= lo[0] && hi[0] <= rhi[0]
        };
        if let Some((stamp, run, found)) = LATEST_RUN.get()
            && stamp == self.stamp
            && holds(run)
        {
            return Some(found);
        }
        let run = (lo, [hi[0] + (RUN - 1.0), hi[1]]);
        let rect = ConvexPolygon::rect(run.0[0], run.0[1], run.1[0], run.1[1]);
        let uv = (self.holds(&rect))
            .then(|| self.region_uv_box(shading, &rect))
            .flatten();
        let found = match uv {
            None => RunTexture::Other,
            Some(uv) => {
                let one = (self.texture_box_of_uv(uv.lo, uv.hi))
                    .and_then(|(tlo, thi)| texture.uniform_colour_in_box(tlo, thi));
                match one {
                    Some(colour) => RunTexture::One(colour, uv),
                    None => match self.edge_image(shading, &uv) {
                        Some(image) => RunTexture::Two(image, uv),
                        None => RunTexture::Other,
                    },
                }
            }
        };
        LATEST_RUN.set(Some((self.stamp, run, found)));
        Some(found)
    }
}
