//! Camera paths: keyframes a camera passes through, for rendering the same
//! scene as a sequence (`quadtex render --path`), so that what changes from
//! frame to frame (the shimmer `compare` measures) can be watched.
//!
//! A path is a list of keys, each a camera pose (`position`, `look_at`,
//! `up`, vertical `fov` in degrees) at a `time` (any unit, strictly
//! increasing). Between keys, `position` and `look_at` follow a
//! Catmull–Rom spline in time (C¹, through every key; the tangent at a key
//! is the chord between its neighbours over their time span, one-sided at
//! the ends), `up` and `fov` are interpolated linearly. Frame `i` of `n`
//! is the pose at `t₀ + (t_last − t₀)·i/(n − 1)` (the first key when
//! `n = 1`). The file format is in `docs/scenes.md`.

use crate::math::Vec3;
use crate::scene::Camera;

/// One keyframe (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Key {
    /// When the camera is here.
    pub time: f64,
    /// Camera position.
    pub position: Vec3,
    /// The point looked at.
    pub look_at: Vec3,
    /// The up direction (fixes the roll).
    pub up: Vec3,
    /// Vertical field of view, degrees.
    pub fov: f64,
}

/// Most keys a path may have.
pub const MAX_PATH_KEYS: usize = 10_000;

/// Most frames one path render may write.
pub const MAX_PATH_FRAMES: u32 = 100_000;

/// A validated camera path: at least one key, times strictly increasing,
/// every key a valid camera (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct CameraPath {
    keys: Vec<Key>,
}

impl CameraPath {
    /// A path through `keys`. Errors name the first key that is not a
    /// camera (non-finite, `look_at` at `position`, `up` along the view, a
    /// field of view outside `(0, 180)`), times that do not increase, no
    /// keys, or more than [`MAX_PATH_KEYS`].
    pub fn new(keys: Vec<Key>) -> Result<CameraPath, String> {
        if keys.is_empty() {
            return Err("the path has no keys".into());
        }
        if keys.len() > MAX_PATH_KEYS {
            return Err(format!("{} keys, more than {MAX_PATH_KEYS}", keys.len()));
        }
        for (i, k) in keys.iter().enumerate() {
            if !k.time.is_finite() {
                return Err(format!("key[{i}].time must be finite"));
            }
            if i > 0 && k.time <= keys[i - 1].time {
                return Err(format!(
                    "key[{i}].time {} does not come after key[{}].time {}",
                    k.time,
                    i - 1,
                    keys[i - 1].time
                ));
            }
            if Camera::new(k.position, k.look_at, k.up, k.fov, 1, 1).is_none() {
                return Err(format!(
                    "key[{i}] is not a camera (look_at at position, up along the view, fov outside (0, 180) or a value not finite)"
                ));
            }
        }
        Ok(CameraPath { keys })
    }

    /// The keys.
    pub fn keys(&self) -> &[Key] {
        &self.keys
    }

    /// The pose at time `t` (clamped to the path's span).
    pub fn pose_at(&self, t: f64) -> Key {
        let k = &self.keys;
        let last = k.len() - 1;
        if k.len() == 1 || t <= k[0].time {
            return k[0];
        }
        if t >= k[last].time {
            return k[last];
        }
        // The segment [i, i + 1] holding t.
        let i = k.partition_point(|key| key.time <= t) - 1;
        let (a, b) = (&k[i], &k[i + 1]);
        let h = b.time - a.time;
        let s = (t - a.time) / h;
        // Tangents (per unit time) at both ends, scaled to the segment.
        let tangent = |j: usize, f: fn(&Key) -> Vec3| -> Vec3 {
            let (lo, hi) = (j.saturating_sub(1), (j + 1).min(last));
            (f(&k[hi]) - f(&k[lo])) * (h / (k[hi].time - k[lo].time))
        };
        let hermite = |f: fn(&Key) -> Vec3| -> Vec3 {
            let (s2, s3) = (s * s, s * s * s);
            f(a) * (2.0 * s3 - 3.0 * s2 + 1.0)
                + tangent(i, f) * (s3 - 2.0 * s2 + s)
                + f(b) * (-2.0 * s3 + 3.0 * s2)
                + tangent(i + 1, f) * (s3 - s2)
        };
        Key {
            time: t,
            position: hermite(|k| k.position),
            look_at: hermite(|k| k.look_at),
            up: a.up * (1.0 - s) + b.up * s,
            fov: a.fov * (1.0 - s) + b.fov * s,
        }
    }

    /// The time of frame `i` of `n` (module docs).
    pub fn frame_time(&self, i: u32, n: u32) -> f64 {
        let (t0, t1) = (self.keys[0].time, self.keys[self.keys.len() - 1].time);
        if n <= 1 {
            return t0;
        }
        t0 + (t1 - t0) * f64::from(i) / f64::from(n - 1)
    }

    /// The camera of frame `i` of `n`, `width × height` pixels; an error
    /// naming the frame when the interpolated pose is not a camera (the
    /// spline passes `look_at` through `position`, or `up` turns along the
    /// view).
    pub fn camera(&self, i: u32, n: u32, width: u32, height: u32) -> Result<Camera, String> {
        let t = self.frame_time(i, n);
        let p = self.pose_at(t);
        Camera::new(p.position, p.look_at, p.up, p.fov, width, height).ok_or_else(|| {
            format!(
                "frame {i} (time {t}): the interpolated camera is degenerate (look_at at position, or up along the view)"
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(time: f64, x: f64) -> Key {
        Key {
            time,
            position: Vec3::new(x, 1.0, 0.0),
            look_at: Vec3::new(x, 0.0, -10.0),
            up: Vec3::new(0.0, 1.0, 0.0),
            fov: 40.0 + time,
        }
    }

    #[test]
    fn frames_pass_through_every_key_and_span_the_path() {
        let path = CameraPath::new(vec![key(0.0, 0.0), key(1.0, 2.0), key(3.0, 3.0)]).unwrap();
        for k in path.keys() {
            let p = path.pose_at(k.time);
            assert!((p.position - k.position).length() < 1e-12);
            assert!((p.look_at - k.look_at).length() < 1e-12);
            assert!((p.fov - k.fov).abs() < 1e-12);
        }
        assert_eq!(path.frame_time(0, 7), 0.0);
        assert_eq!(path.frame_time(6, 7), 3.0);
        assert_eq!(path.frame_time(0, 1), 0.0);
        // Clamped beyond the ends.
        assert_eq!(path.pose_at(-5.0), path.keys()[0]);
        assert_eq!(path.pose_at(9.0), path.keys()[2]);
    }

    #[test]
    fn a_straight_uniform_move_stays_straight_and_uniform() {
        // Keys equally spaced in time and space: the spline is the line.
        let path =
            CameraPath::new((0..4).map(|i| key(f64::from(i), f64::from(i))).collect()).unwrap();
        for j in 0..=30 {
            let t = 3.0 * f64::from(j) / 30.0;
            let p = path.pose_at(t);
            assert!((p.position.x - t).abs() < 1e-12, "{t}: {:?}", p.position);
            assert!((p.position.y - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn the_spline_is_smooth_across_keys() {
        let path = CameraPath::new(vec![
            key(0.0, 0.0),
            key(1.0, 3.0),
            key(1.5, 3.5),
            key(4.0, 0.0),
        ])
        .unwrap();
        // Velocity just before and after the inner keys agrees.
        for t in [1.0, 1.5] {
            let e = 1e-6;
            let v = |a: f64, b: f64| {
                (path.pose_at(b).position - path.pose_at(a).position) * (1.0 / (b - a))
            };
            let (before, after) = (v(t - 2.0 * e, t - e), v(t + e, t + 2.0 * e));
            assert!(
                (before - after).length() < 1e-4,
                "{t}: {before:?} vs {after:?}"
            );
        }
    }

    #[test]
    fn bad_paths_are_refused_by_key() {
        assert!(CameraPath::new(vec![]).unwrap_err().contains("no keys"));
        let e = CameraPath::new(vec![key(0.0, 0.0), key(0.0, 1.0)]).unwrap_err();
        assert!(e.contains("key[1].time"), "{e}");
        let mut bad = key(1.0, 0.0);
        bad.look_at = bad.position;
        let e = CameraPath::new(vec![key(0.0, 0.0), bad]).unwrap_err();
        assert!(e.starts_with("key[1] is not a camera"), "{e}");
        let mut nan = key(1.0, 0.0);
        nan.fov = f64::NAN;
        assert!(CameraPath::new(vec![nan]).is_err());
    }

    #[test]
    fn a_degenerate_frame_is_named() {
        // Looking back along the path through the position: the spline
        // crosses look_at = position half-way.
        let a = Key {
            time: 0.0,
            position: Vec3::new(0.0, 0.0, 0.0),
            look_at: Vec3::new(1.0, 0.0, 0.0),
            up: Vec3::new(0.0, 1.0, 0.0),
            fov: 45.0,
        };
        let b = Key {
            time: 1.0,
            position: Vec3::new(1.0, 0.0, 0.0),
            look_at: Vec3::new(0.0, 0.0, 0.0),
            ..a
        };
        let path = CameraPath::new(vec![a, b]).unwrap();
        let e = path.camera(1, 3, 64, 32).unwrap_err();
        assert!(e.starts_with("frame 1 (time 0.5)"), "{e}");
        assert!(path.camera(0, 3, 64, 32).is_ok());
    }
}
