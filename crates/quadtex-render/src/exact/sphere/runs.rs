//! Runs of pixels inside a sphere's outline that one texture square holds
//! ([`SphereView::uniform_run`]): the closed-form UV box ([`super::arcs`])
//! of the supports of several pixels of a row at once, so that the disc's
//! wide uniform stretches cost one box for a run, not one a pixel.

use quadtex_core::{ConvexPolygon, Rgba};

use crate::scene::Lighting;

use super::super::lighting::Shading;
use super::SphereView;

/// Pixels a run spans: the run's box is a little wider than one pixel's,
/// so that a checker square holds most runs a pixel's box would fit in.
const RUN: f64 = 8.0;

/// The latest run a thread looked at: the view's stamp, the run's support
/// box, and the colour that holds it (`None`: none does).
type KeptRun = (u64, ([f64; 2], [f64; 2]), Option<Rgba>);

thread_local! {
    static LATEST_RUN: std::cell::Cell<Option<KeptRun>> = const { std::cell::Cell::new(None) };
}

impl SphereView {
    /// The colour of the texture over all of the support the shading's
    /// region was cut from, when one texture square holds the sphere's UV
    /// over a run of supports along the row from it (the support's box
    /// stretched [`RUN`] − 1 pixels right, lying inside the outline): kept
    /// by the thread, so the next pixels of the run find it. Only for an
    /// unlit, textured sphere (under a light the run's cosine spreads too
    /// far to take one colour). `None` otherwise, or when no square holds
    /// the run.
    pub(super) fn uniform_run(&self, shading: &Shading<'_>) -> Option<Rgba> {
        let scene = shading.frame.scene;
        if !matches!(scene.lighting, Lighting::Unlit) {
            return None;
        }
        let texture = shading.frame.texture(self.surface)?;
        let (lo, hi) = shading.support;
        let holds = |(rlo, rhi): ([f64; 2], [f64; 2])| {
            rlo[1] == lo[1] && rhi[1] == hi[1] && rlo[0] <= lo[0] && hi[0] <= rhi[0]
        };
        if let Some((stamp, run, colour)) = LATEST_RUN.get()
            && stamp == self.stamp
            && holds(run)
        {
            return colour;
        }
        let run = (lo, [hi[0] + (RUN - 1.0), hi[1]]);
        let rect = ConvexPolygon::rect(run.0[0], run.0[1], run.1[0], run.1[1]);
        let colour = if self.holds(&rect) {
            self.uv_box(&rect, None, &scene.camera)
                .and_then(|uv| self.texture_box_of_uv(uv.lo, uv.hi))
                .and_then(|(tlo, thi)| texture.uniform_colour_in_box(tlo, thi))
        } else {
            None
        };
        LATEST_RUN.set(Some((self.stamp, run, colour)));
        colour
    }
}
