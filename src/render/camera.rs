//! Camera projection from plain numbers, matching usd-core's
//! `UsdGeom.Camera(prim).GetCamera(t).frustum` (GfCamera → GfFrustum).
//!
//! UsdGeomCamera stores `focalLength` and the apertures in the same unit
//! (tenths of a scene unit by convention: millimetres in a centimetre scene).
//! GfCamera builds the frustum window from them:
//!
//! - perspective: the window on the plane at distance 1 in front of the eye is
//!   `[(-h/2 + ho) / f, (h/2 + ho) / f] × [(-v/2 + vo) / f, (v/2 + vo) / f]`
//!   (h, v the apertures, ho, vo the aperture offsets, f the focal length; the
//!   tenths cancel);
//! - orthographic: the window is the aperture itself converted to scene units,
//!   `[(-h/2 + ho) / 10, (h/2 + ho) / 10] × ...`.
//!
//! The camera looks down its local −Z with +Y up; its local-to-world matrix is
//! reduced to a position and a rotation as GfFrustum does it
//! ([`frustum_rotation`]: Gf's iterative orthonormalisation, not the closest
//! rotation, which differs for a sheared or non-uniformly scaled camera).
//!
//! **Conform policy.** When the image aspect (width / height) differs from the
//! window's, the horizontal extent is kept and the vertical extent becomes
//! `width / aspect`, centred on the window's centre (CameraUtil's
//! `MatchHorizontally`). Pixels are then square.
//!
//! Pixel coordinates: x to the right, y down, pixel (i, j) covers
//! `[i, i+1) × [j, j+1)`; NDC (−1, 1) is the top-left corner of the image.

use glam::{DMat3, DMat4, DVec2, DVec3};

/// `projection` of a UsdGeomCamera.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Projection {
    Perspective,
    Orthographic,
}

/// A UsdGeomCamera's parameters at one time, in its own units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraParams {
    pub focal_length: f64,
    pub horizontal_aperture: f64,
    pub vertical_aperture: f64,
    pub horizontal_aperture_offset: f64,
    pub vertical_aperture_offset: f64,
    /// `clippingRange` (near, far), scene units.
    pub near: f64,
    pub far: f64,
    pub projection: Projection,
    /// The camera prim's local-to-world transform (column-vector form).
    pub camera_to_world: DMat4,
}

impl Default for CameraParams {
    /// UsdGeomCamera's fallbacks.
    fn default() -> Self {
        CameraParams {
            focal_length: 50.0,
            horizontal_aperture: 20.955,
            vertical_aperture: 15.2908,
            horizontal_aperture_offset: 0.0,
            vertical_aperture_offset: 0.0,
            near: 1.0,
            far: 1_000_000.0,
            projection: Projection::Perspective,
            camera_to_world: DMat4::IDENTITY,
        }
    }
}

/// A 2-D window `[x0, x1] × [y0, y1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    pub x0: f64,
    pub x1: f64,
    pub y0: f64,
    pub y1: f64,
}

/// What is wrong with a camera: the attribute and a message.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraProblem {
    pub attribute: &'static str,
    pub message: String,
}

impl CameraParams {
    /// Checks the numbers can make a frustum.
    pub fn validate(&self) -> Result<(), CameraProblem> {
        let bad = |attribute: &'static str, message: String| Err(CameraProblem { attribute, message });
        let fin = |a: &'static str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                bad(a, format!("{v} is not finite"))
            }
        };
        fin("focalLength", self.focal_length)?;
        fin("horizontalAperture", self.horizontal_aperture)?;
        fin("verticalAperture", self.vertical_aperture)?;
        fin("horizontalApertureOffset", self.horizontal_aperture_offset)?;
        fin("verticalApertureOffset", self.vertical_aperture_offset)?;
        if self.horizontal_aperture <= 0.0 {
            return bad(
                "horizontalAperture",
                format!("aperture {} must be positive", self.horizontal_aperture),
            );
        }
        if self.vertical_aperture <= 0.0 {
            return bad(
                "verticalAperture",
                format!("aperture {} must be positive", self.vertical_aperture),
            );
        }
        if self.projection == Projection::Perspective && self.focal_length <= 0.0 {
            return bad(
                "focalLength",
                format!(
                    "focal length {} must be positive for a perspective camera",
                    self.focal_length
                ),
            );
        }
        if !self.near.is_finite() || self.far.is_nan() {
            return bad("clippingRange", format!("({}, {}) is not finite", self.near, self.far));
        }
        if self.projection == Projection::Perspective && self.near <= 0.0 {
            return bad(
                "clippingRange",
                format!("near distance {} must be positive for a perspective camera", self.near),
            );
        }
        if self.far <= self.near {
            return bad(
                "clippingRange",
                format!("far {} must be greater than near {}", self.far, self.near),
            );
        }
        if !self.camera_to_world.is_finite() || self.camera_to_world.determinant().abs() < 1e-300 {
            return bad("xformOp", "the camera's transform is singular or not finite".into());
        }
        Ok(())
    }

    /// GfCamera's frustum window (before any conform).
    pub fn window(&self) -> Window {
        let (hx, hy) = (self.horizontal_aperture / 2.0, self.vertical_aperture / 2.0);
        let (ox, oy) = (self.horizontal_aperture_offset, self.vertical_aperture_offset);
        let scale = match self.projection {
            // Apertures and focal length share a unit; the tenths cancel.
            Projection::Perspective => 1.0 / self.focal_length,
            // Apertures are in tenths of a scene unit.
            Projection::Orthographic => 0.1,
        };
        Window {
            x0: (-hx + ox) * scale,
            x1: (hx + ox) * scale,
            y0: (-hy + oy) * scale,
            y1: (hy + oy) * scale,
        }
    }
}

/// Keeps the window's horizontal extent and sets the vertical one to
/// `width / aspect` around the same centre (CameraUtil `MatchHorizontally`).
pub fn conform_match_horizontally(w: Window, aspect: f64) -> Window {
    let cy = 0.5 * (w.y0 + w.y1);
    let half = 0.5 * (w.x1 - w.x0) / aspect;
    Window {
        y0: cy - half,
        y1: cy + half,
        ..w
    }
}

/// The rotation GfFrustum keeps of a camera's local-to-world matrix
/// (`SetPositionAndRotationFromMatrix`), in column form (`m`'s columns are
/// Gf's rows, the camera's axes in world space):
///
/// 1. the axes orthonormalised as `GfMatrix4d::Orthonormalize` does
///    ([`crate::gf::orthonormalized`]);
/// 2. a left-handed result mirrored back by negating its x axis;
/// 3. that matrix, orthonormal only to about 1e-6, read as a `GfRotation`:
///    a quaternion by the largest diagonal entry, its imaginary part giving
///    the axis and its real part `r` the angle `2·acos(r)` (so the rotation
///    is exact, and what Gf's view matrix is built from).
///
/// This is not the closest rotation (a polar decomposition): for a sheared
/// or non-uniformly scaled camera the two differ by degrees.
fn frustum_rotation(m: DMat3) -> DMat3 {
    let mut r = crate::gf::orthonormalized(m);
    if r.determinant() < 0.0 {
        r.x_axis = -r.x_axis;
    }
    let q = crate::gf::rotation_quaternion(&r);
    let imaginary = DVec3::new(q.x, q.y, q.z);
    let len = imaginary.length();
    // GfRotation keeps the identity for an axis shorter than this.
    if len.is_nan() || len <= 1e-10 {
        return DMat3::IDENTITY;
    }
    DMat3::from_axis_angle(imaginary / len, 2.0 * q.w.acos())
}

/// A camera set up for one image: world → pixels.
#[derive(Debug, Clone, Copy)]
pub struct Projector {
    /// World → camera (orthonormal).
    pub world_to_camera: DMat4,
    /// Camera → world (orthonormal).
    pub camera_to_world: DMat4,
    /// The conformed window.
    pub window: Window,
    pub projection: Projection,
    pub near: f64,
    pub far: f64,
    pub width: usize,
    pub height: usize,
    /// Pixels per window unit (the same in x and y after conforming).
    scale: f64,
}

impl Projector {
    /// Sets up `cam` for a `width` × `height` image.
    pub fn new(cam: &CameraParams, width: usize, height: usize) -> Projector {
        let aspect = width as f64 / height as f64;
        let window = conform_match_horizontally(cam.window(), aspect);
        let m = cam.camera_to_world;
        let rot = frustum_rotation(DMat3::from_mat4(m));
        let camera_to_world = DMat4::from_cols(
            rot.x_axis.extend(0.0),
            rot.y_axis.extend(0.0),
            rot.z_axis.extend(0.0),
            m.w_axis.truncate().extend(1.0),
        );
        Projector {
            world_to_camera: camera_to_world.inverse(),
            camera_to_world,
            window,
            projection: cam.projection,
            near: cam.near,
            far: cam.far,
            width,
            height,
            scale: width as f64 / (window.x1 - window.x0),
        }
    }

    /// A world point in camera space (the camera looks down −Z).
    pub fn to_camera(&self, p: DVec3) -> DVec3 {
        self.world_to_camera.transform_point3(p)
    }

    /// Distance in front of the camera along its view axis.
    pub fn depth(p_cam: DVec3) -> f64 {
        -p_cam.z
    }

    /// Pixel position of a camera-space point (perspective points need depth > 0).
    pub fn camera_to_pixel(&self, p: DVec3) -> DVec2 {
        let (sx, sy) = match self.projection {
            Projection::Perspective => {
                let d = -p.z;
                (p.x / d, p.y / d)
            }
            Projection::Orthographic => (p.x, p.y),
        };
        let w = &self.window;
        DVec2::new((sx - w.x0) * self.scale, (w.y1 - sy) * self.scale)
    }

    /// Pixel position and depth of a world point, or None outside the clipping range.
    pub fn project(&self, p: DVec3) -> Option<(DVec2, f64)> {
        let c = self.to_camera(p);
        let d = Self::depth(c);
        if d < self.near || d > self.far {
            return None;
        }
        Some((self.camera_to_pixel(c), d))
    }

    /// Pixels per scene unit for a length perpendicular to the view axis at `depth`.
    pub fn pixels_per_unit(&self, depth: f64) -> f64 {
        match self.projection {
            Projection::Perspective => self.scale / depth,
            Projection::Orthographic => self.scale,
        }
    }

    /// The eye position in world space.
    pub fn eye(&self) -> DVec3 {
        self.camera_to_world.w_axis.truncate()
    }

    /// The world-space view direction (camera −Z).
    pub fn forward(&self) -> DVec3 {
        -self.camera_to_world.z_axis.truncate()
    }

    /// Whether the camera is perspective.
    pub fn is_perspective(&self) -> bool {
        self.projection == Projection::Perspective
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn default_window_matches_gf_camera() {
        // Gf.Camera().frustum.window = [(-0.20955, -0.152908)...(0.20955, 0.152908)]
        let w = CameraParams::default().window();
        assert!(close(w.x0, -0.20955, 1e-12) && close(w.x1, 0.20955, 1e-12));
        assert!(close(w.y0, -0.152908, 1e-12) && close(w.y1, 0.152908, 1e-12));
        let o = CameraParams {
            projection: Projection::Orthographic,
            ..Default::default()
        }
        .window();
        assert!(close(o.x1, 1.04775, 1e-12) && close(o.y1, 0.76454, 1e-12));
    }

    #[test]
    fn centre_and_corners_project_where_expected() {
        let cam = CameraParams {
            focal_length: 50.0,
            horizontal_aperture: 36.0,
            vertical_aperture: 24.0,
            camera_to_world: DMat4::from_translation(DVec3::new(1.0, 2.0, 10.0)),
            ..Default::default()
        };
        let p = Projector::new(&cam, 300, 200);
        // On the axis, 10 units in front: the image centre.
        let (px, d) = p.project(DVec3::new(1.0, 2.0, 0.0)).unwrap();
        assert!(close(px.x, 150.0, 1e-9) && close(px.y, 100.0, 1e-9) && close(d, 10.0, 1e-12));
        // The window's right edge at depth 10 is x = 10 * 18 / 50 = 3.6.
        let (px, _) = p.project(DVec3::new(1.0 + 3.6, 2.0 + 2.4, 0.0)).unwrap();
        assert!(close(px.x, 300.0, 1e-9) && close(px.y, 0.0, 1e-9), "{px:?}");
        // Behind the camera or beyond the clipping range: not projected.
        assert!(p.project(DVec3::new(1.0, 2.0, 20.0)).is_none());
        assert!(p.project(DVec3::new(1.0, 2.0, 9.5)).is_none());
        assert!(close(p.pixels_per_unit(10.0), 300.0 / 7.2, 1e-9));
    }

    #[test]
    fn conform_keeps_horizontal_and_centres_vertical() {
        let cam = CameraParams {
            vertical_aperture_offset: 3.0,
            ..Default::default()
        };
        let w = conform_match_horizontally(cam.window(), 2.0);
        let raw = cam.window();
        assert_eq!((w.x0, w.x1), (raw.x0, raw.x1));
        assert!(close(w.y1 - w.y0, (raw.x1 - raw.x0) / 2.0, 1e-12));
        assert!(close(w.y0 + w.y1, raw.y0 + raw.y1, 1e-12));
    }

    #[test]
    fn orthographic_and_rotated_cameras() {
        // Camera at (0, 0, 5) turned 90° about Y: looks down world −X.
        let m =
            DMat4::from_translation(DVec3::new(0.0, 0.0, 5.0)) * DMat4::from_rotation_y(std::f64::consts::FRAC_PI_2);
        let cam = CameraParams {
            projection: Projection::Orthographic,
            horizontal_aperture: 40.0,
            vertical_aperture: 40.0,
            near: 0.0,
            camera_to_world: m,
            ..Default::default()
        };
        let p = Projector::new(&cam, 100, 100);
        // Window is 4 × 4 units; a point 3 units along −X and 1 unit up.
        let (px, d) = p.project(DVec3::new(-3.0, 1.0, 5.0)).unwrap();
        assert!(close(d, 3.0, 1e-12));
        assert!(close(px.x, 50.0, 1e-9) && close(px.y, 25.0, 1e-9), "{px:?}");
        assert!(close(p.pixels_per_unit(7.0), 25.0, 1e-12));
        // A uniformly scaled camera projects the same.
        let scaled = CameraParams {
            camera_to_world: m * DMat4::from_scale(DVec3::splat(3.0)),
            ..cam
        };
        let q = Projector::new(&scaled, 100, 100);
        let (qx, _) = q.project(DVec3::new(-3.0, 1.0, 5.0)).unwrap();
        assert!((qx - px).length() < 1e-9);
    }

    #[test]
    fn validation_names_the_attribute() {
        let bad = |c: CameraParams| c.validate().unwrap_err().attribute;
        let d = CameraParams::default();
        assert_eq!(bad(CameraParams { focal_length: 0.0, ..d }), "focalLength");
        assert_eq!(
            bad(CameraParams {
                horizontal_aperture: 0.0,
                ..d
            }),
            "horizontalAperture"
        );
        assert_eq!(
            bad(CameraParams {
                vertical_aperture: -1.0,
                ..d
            }),
            "verticalAperture"
        );
        assert_eq!(
            bad(CameraParams {
                near: 5.0,
                far: 1.0,
                ..d
            }),
            "clippingRange"
        );
        assert_eq!(bad(CameraParams { near: 0.0, ..d }), "clippingRange");
        assert!(d.validate().is_ok());
    }

    #[test]
    fn frustum_rotation_ignores_a_uniform_scale_of_any_size() {
        // The rotation of s·R is R for every s > 0; mirrored, R with x flipped.
        let rot = DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
        for s in [1e-12, 1e-9, 1.0, 1e9, 1e12] {
            let got = frustum_rotation(rot * s);
            assert!(got.abs_diff_eq(rot, 1e-12), "scale {s}: {got}");
            let mirror = DMat3::from_diagonal(DVec3::new(-1.0, 1.0, 1.0));
            let got = frustum_rotation(rot * mirror * s);
            assert!(got.abs_diff_eq(rot, 1e-12), "mirrored, scale {s}: {got}");
        }
    }

    #[test]
    fn validation_refuses_non_finite_clipping_and_singular_transforms() {
        let attr = |c: CameraParams| c.validate().map_err(|e| e.attribute);
        let d = CameraParams::default();
        assert_eq!(attr(CameraParams { near: f64::NAN, ..d }), Err("clippingRange"));
        assert_eq!(attr(CameraParams { far: f64::NAN, ..d }), Err("clippingRange"));
        // Flattened (determinant 0) and not finite.
        for m in [
            DMat4::from_scale(DVec3::new(1.0, 1.0, 0.0)),
            DMat4::from_translation(DVec3::splat(f64::NAN)),
        ] {
            let mut c = d;
            c.camera_to_world = m;
            assert_eq!(attr(c), Err("xformOp"), "{m}");
        }
    }

    #[test]
    fn project_keeps_both_ends_of_the_clipping_range() {
        // The range is closed, as prepare.rs's clipping is.
        let cam = CameraParams {
            near: 0.5,
            far: 20.0,
            ..Default::default()
        };
        let p = Projector::new(&cam, 100, 100);
        for d in [0.5, 20.0] {
            assert_eq!(p.project(DVec3::new(0.0, 0.0, -d)).map(|(_, depth)| depth), Some(d));
        }
        assert!(p.project(DVec3::new(0.0, 0.0, -20.25)).is_none());
    }

    #[test]
    fn scaled_and_mirrored_camera_projects_as_gf_frustum() {
        // Reference from usd-core: Gf.Camera(m, Perspective, 36, 24, 2, -1.5, 35, (0.5, 200)).frustum
        // with m = scale (±2, 3, 0.5) · rotate(axis (1, 2, 3), 0.7 rad) · translate (1.5, -2, 8) in
        // Gf's row-vector order, window conformed to 320×200 as test_render.py's predict() does.
        // usd-core gives one frustum for both signs: it orthonormalises, then mirrors x back. Scales
        // off 1 make the first Newton step change every entry, so a premature stop would show.
        let rot = DMat4::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
        let eye = DVec3::new(1.5, -2.0, 8.0);
        for sx in [2.0, -2.0] {
            let cam = CameraParams {
                focal_length: 35.0,
                horizontal_aperture: 36.0,
                vertical_aperture: 24.0,
                horizontal_aperture_offset: 2.0,
                vertical_aperture_offset: -1.5,
                near: 0.5,
                far: 200.0,
                camera_to_world: DMat4::from_translation(eye) * rot * DMat4::from_scale(DVec3::new(sx, 3.0, 0.5)),
                ..Default::default()
            };
            let p = Projector::new(&cam, 320, 200);
            for (world, pixel, depth) in [
                (
                    DVec3::ZERO,
                    DVec2::new(230.17427180434285, 78.76433270658143),
                    8.06301523119499,
                ),
                (
                    DVec3::new(1.0, -1.0, 2.0),
                    DVec2::new(246.00295363098212, 117.11711403400646),
                    5.76485279982868,
                ),
            ] {
                let (px, d) = p.project(world).unwrap();
                assert!(
                    (px - pixel).length() < 1e-9 && close(d, depth, 1e-12),
                    "x scale {sx}: {px:?} {d}"
                );
            }
            // Gf.Frustum's position and ComputeViewDirection().
            assert!((p.eye() - eye).length() < 1e-12);
            let forward = DVec3::new(-0.39473979817379956, 0.07139249941787584, -0.9160150668873174);
            assert!((p.forward() - forward).length() < 1e-12, "{:?}", p.forward());
        }
    }

    /// Gf's row-major 4 × 4 (row-vector convention) as a column-form matrix.
    fn from_gf_rows(rows: [[f64; 4]; 4]) -> DMat4 {
        DMat4::from_cols_array_2d(&rows)
    }

    #[test]
    fn sheared_and_non_uniformly_scaled_cameras_project_as_gf_frustum() {
        // Reference values computed with usd-core 26.11 in Python: for each
        // matrix m,
        // Gf.Camera(m, Perspective, 36, 24, 2, -1.5, 35, (0.5, 200)).frustum,
        // its window conformed to 320×200 as test_render.py's predict() does;
        // the pixel is (ndc + 1)/2·320, (1 − ndc.y)/2·200 of
        // view·projection, the depth −z of view; the rotation rows are those
        // of ComputeViewInverse(). The matrices:
        // - "shear": rows (1, 0.4, 0), (0, 1, 0), (0.25, −0.3, 1), translation
        //   (0.5, −0.3, 11);
        // - "rotate then scale": Gf.Rotation((1, 2, 3) normalised, 0.7 rad),
        //   then a scale (2, 0.5, 1.5) along the world axes (a parent's
        //   scale), then translate (1.5, −2, 8): rows shown below;
        // - the same with scale (−2, 0.5, 1.5): left-handed, mirrored back.
        // The closest rotation (a polar decomposition, as painterly once
        // used) puts these points 8 to 23 px from usd-core's.
        type Case = ([[f64; 4]; 4], [[f64; 3]; 3], [(DVec3, DVec2, f64); 2]);
        let cases: [(&str, Case); 3] = [
            (
                "shear",
                (
                    [
                        [1.0, 0.4, 0.0, 0.0],
                        [0.0, 1.0, 0.0, 0.0],
                        [0.25, -0.3, 1.0, 0.0],
                        [0.5, -0.3, 11.0, 1.0],
                    ],
                    [
                        [0.9697216231383229, 0.2034243782712832, -0.13512400209777214],
                        [-0.17883563939944477, 0.96831011028932, 0.1743368704321522],
                        [0.16630630685144984, -0.1448932456549551, 0.9753707806085871],
                    ],
                    [
                        (
                            DVec3::ZERO,
                            DVec2::new(172.67305090511883, 130.73798746813333),
                            10.855699713816668,
                        ),
                        (
                            DVec3::new(1.0, -1.0, 2.0),
                            DVec2::new(198.64590191975066, 171.24415741217462),
                            8.59375860009309,
                        ),
                    ],
                ),
            ),
            (
                "rotate then scale",
                (
                    [
                        [1.56327834781405, 0.2750586153521792, -0.44093681765787085, 0.0],
                        [-0.9658585684284244, 0.41601506688731726, 0.4094345083324715, 0.0],
                        [0.7894795963475996, -0.03569624970893792, 1.374022600330976, 0.0],
                        [1.5, -2.0, 8.0, 1.0],
                    ],
                    [
                        [0.7288537466690498, 0.6368726750190771, -0.2513273001099043],
                        [-0.568919279097272, 0.7675829194345095, 0.29520724188921255],
                        [0.38092396857893995, -0.07217795789879856, 0.921784829857614],
                    ],
                    [
                        (
                            DVec3::ZERO,
                            DVec2::new(226.48286244695163, 85.63270276216109),
                            8.090020507526917,
                        ),
                        (
                            DVec3::new(1.0, -1.0, 2.0),
                            DVec2::new(237.83276064126613, 125.28878174553087),
                            5.793348921333951,
                        ),
                    ],
                ),
            ),
            (
                "mirrored",
                (
                    [
                        [-1.56327834781405, 0.2750586153521792, -0.44093681765787085, 0.0],
                        [0.9658585684284244, 0.41601506688731726, 0.4094345083324715, 0.0],
                        [-0.7894795963475996, -0.03569624970893792, 1.374022600330976, 0.0],
                        [1.5, -2.0, 8.0, 1.0],
                    ],
                    [
                        [0.7288537466690498, -0.6368726750190771, 0.2513273001099043],
                        [0.568919279097272, 0.7675829194345095, 0.29520724188921255],
                        [-0.38092396857893995, -0.07217795789879856, 0.921784829857614],
                    ],
                    [
                        (
                            DVec3::ZERO,
                            DVec2::new(-53.81708518583455, 161.8945112311027),
                            6.947248601790099,
                        ),
                        (
                            DVec3::new(1.0, -1.0, 2.0),
                            DVec2::new(-2.0125182861819013, 160.7089861967085),
                            5.412424952755012,
                        ),
                    ],
                ),
            ),
        ];
        for (name, (rows, rotation, points)) in cases {
            let cam = CameraParams {
                focal_length: 35.0,
                horizontal_aperture: 36.0,
                vertical_aperture: 24.0,
                horizontal_aperture_offset: 2.0,
                vertical_aperture_offset: -1.5,
                near: 0.5,
                far: 200.0,
                camera_to_world: from_gf_rows(rows),
                ..Default::default()
            };
            let p = Projector::new(&cam, 320, 200);
            for (k, row) in rotation.iter().enumerate() {
                let axis = p.camera_to_world.col(k).truncate();
                assert!(
                    (axis - DVec3::from_array(*row)).length() < 1e-12,
                    "{name}: axis {k} {axis:?} vs {row:?}"
                );
            }
            for (world, pixel, depth) in points {
                let (px, d) = p.project(world).unwrap();
                assert!(
                    (px - pixel).length() < 1e-9 && close(d, depth, 1e-12),
                    "{name}: {world:?} at {px:?} depth {d}, usd-core {pixel:?} {depth}"
                );
            }
        }
    }

    #[test]
    fn gf_orthonormalize_keeps_nearly_parallel_axes_normalised_only() {
        // Two axes within 1e-6 of each other once normalised: Gf gives up
        // and leaves them normalised (usd-core: Orthonormalize() returns
        // False and the rows come back normalised).
        let m = DMat3::from_cols(
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(3.0, 1.5e-6, 0.0),
            DVec3::new(0.0, 0.0, 0.5),
        );
        let got = crate::gf::orthonormalized(m);
        let want = DMat3::from_cols(DVec3::X, DVec3::new(3.0, 1.5e-6, 0.0).normalize(), DVec3::Z);
        assert!(got.abs_diff_eq(want, 1e-15), "{got}");
    }
}
