//! The comparison harness checked against itself: supersampling converges,
//! and the closed-form reference agrees with a dense supersampled one.
#![allow(clippy::unwrap_used, clippy::expect_used)]

#[path = "../../quadtex-render/tests/common/scenes.rs"]
mod scenes;

use quadtex_eval::{metrics, reference};
use quadtex_render::{RenderOptions, TextureFilter, render};
use scenes::{grazing, render_with};

/// Sanity check of the comparison harness: stratified supersampling
/// converges to the reference as the sample count grows, and the quadtree
/// (with its silhouette split) beats 64 samples on the whole frame,
/// horizon included.
#[test]
fn supersampling_error_falls_as_samples_grow() {
    let scene = grazing(64, 36, 1.5);
    let go = |filter| render_with(&scene, filter);
    let reference = go(TextureFilter::Supersample(32));
    let errors: Vec<f64> = [1, 2, 4, 8]
        .iter()
        .map(|&n| metrics::rmse(&go(TextureFilter::Supersample(n)), &reference).unwrap())
        .collect();
    assert!(
        errors.windows(2).all(|w| w[1] < w[0]),
        "supersampling errors for 1, 4, 16, 64 samples: {errors:?}"
    );
    let quadtree = metrics::rmse(&go(TextureFilter::default()), &reference).unwrap();
    assert!(
        quadtree < errors[3],
        "quadtree {quadtree} vs 64 samples {}",
        errors[3]
    );
    eprintln!("supersampling {errors:?}, quadtree {quadtree}");
}

/// The closed-form checkerboard (exact screen-space clipping of every
/// checker cell against every pixel) agrees with a 4096-sample supersampled
/// reference, and ranks the filters as that reference does.
#[test]
fn closed_form_checkerboard_validates_the_reference() {
    let (w, h) = (48u32, 32u32);
    let scene = grazing(w, h, 1.5);
    let exact = reference::closed_form_plane(&scene, w, h).expect("a plane scene");
    let go = |filter| render_with(&scene, filter);
    let (reference, defined) =
        metrics::rmse_where_defined(&go(TextureFilter::Supersample(64)), &exact).unwrap();
    assert!(
        defined == 1.0,
        "closed form defined on {defined} of the pixels"
    );
    // 4096 jittered samples: the reference's own error is small but not zero.
    assert!(
        reference < 0.004,
        "4096-sample reference vs closed form: {reference}"
    );
    let (quadtree, _) = metrics::rmse_where_defined(&go(TextureFilter::default()), &exact).unwrap();
    let (ewa, _) = metrics::rmse_where_defined(
        &go(TextureFilter::Ewa {
            max_anisotropy: 8.0,
        }),
        &exact,
    )
    .unwrap();
    assert!(quadtree < ewa, "quadtree {quadtree}, EWA {ewa}");
    eprintln!(
        "vs closed form on {:.0}% of pixels: 4096-spp {reference:.5}, quadtree {quadtree:.5}, EWA {ewa:.5}",
        100.0 * defined
    );
}

/// A reference draws its own jitter stream: a contender with the
/// reference's sample count is not the reference. Its error is that of two
/// independent 64-sample images, about √2 × one image's 64-sample noise
/// (measured as its distance from a 1024-sample reference).
#[test]
fn a_contender_with_the_references_sample_count_is_not_the_reference() {
    let scene = grazing(48, 32, 1.5);
    let go = |filter, seed| {
        render(
            &scene,
            &RenderOptions {
                filter,
                seed,
                ..RenderOptions::default()
            },
            &|_, _| {},
        )
        .unwrap()
        .0
    };
    let reference = go(
        TextureFilter::Supersample(8),
        quadtex_render::REFERENCE_SEED,
    );
    let contender = go(TextureFilter::Supersample(8), 0);
    let dense = go(
        TextureFilter::Supersample(32),
        quadtex_render::REFERENCE_SEED,
    );
    let same_count = metrics::rmse(&contender, &reference).unwrap();
    let noise = metrics::rmse(&contender, &dense).unwrap();
    eprintln!("64 spp vs 64-spp reference {same_count:.5}; vs 1024-spp reference {noise:.5}");
    assert!(same_count > 0.0, "the contender equals its reference");
    let ratio = same_count / noise;
    assert!(
        (1.0..2.5).contains(&ratio),
        "two independent 64-sample images differ by {same_count}, one differs from the truth by {noise} (ratio {ratio}, expected about 1.4)"
    );
}
