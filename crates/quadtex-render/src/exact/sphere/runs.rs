//! Runs of pixels inside a sphere's outline that one texture square holds
//! ([`SphereView::uniform_run`]): the closed-form UV box ([`super::arcs`])
//! of the supports of several pixels of a row at once, so that the disc's
//! wide uniform stretches cost one box for a run, not one a pixel. Under
//! a light each pixel still carries its own light bound
//! ([`SphereView::light_bound`]: the run's cosine range holds its own).

use quadtex_core::{ConvexPolygon, Rgba};

use super::super::lighting::Shading;
use super::SphereView;
use super::arcs::UvBox;

/// Pixels a run spans: the run's box is a little wider than one pixel's,
/// so that a checker square holds most runs a pixel's box would fit in.
const RUN: f64 = 8.0;

/// The latest run a thread looked at: the view's stamp, the run's support
/// box, and the colour that holds it with the run's UV box (`None`: none
/// does).
type KeptRun = (u64, ([f64; 2], [f64; 2]), Option<(Rgba, UvBox)>);

thread_local! {
    static LATEST_RUN: std::cell::Cell<Option<KeptRun>> = const { std::cell::Cell::new(None) };
}

impl SphereView {
    /// The colour of the texture over all of the support the shading's
    /// region was cut from, and the closed-form UV box (with the light's
    /// cosine) of a run of supports along the row from it (the support's
    /// box stretched [`RUN`] − 1 pixels right, lying inside the outline),
    /// when one texture square holds that box: kept by the thread, so the
    /// next pixels of the run find it. `None` for an untextured sphere, or
    /// when no square holds the run.
    pub(super) fn uniform_run(&self, shading: &Shading<'_>) -> Option<(Rgba, UvBox)> {
        let texture = shading.frame.texture(self.surface)?;
        let (lo, hi) = shading.support;
        let holds = |(rlo, rhi): ([f64; 2], [f64; 2])| {
            rlo[1] == lo[1] && rhi[1] == hi[1] && rlo[0] <= lo[0] && hi[0] <= rhi[0]
        };
        if let Some((stamp, run, found)) = LATEST_RUN.get()
            && stamp == self.stamp
            && holds(run)
        {
            return found;
        }
        let run = (lo, [hi[0] + (RUN - 1.0), hi[1]]);
        let rect = ConvexPolygon::rect(run.0[0], run.0[1], run.1[0], run.1[1]);
        let found = if self.holds(&rect) {
            self.region_uv_box(shading, &rect).and_then(|uv| {
                let (tlo, thi) = self.texture_box_of_uv(uv.lo, uv.hi)?;
                Some((texture.uniform_colour_in_box(tlo, thi)?, uv))
            })
        } else {
            None
        };
        LATEST_RUN.set(Some((self.stamp, run, found)));
        found
    }
}
