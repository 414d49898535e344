//! Rademacher's warm/cool two-light NPR shading (Rademacher 1999, §3.2.4):
//!
//! ```text
//! C_final = k_a·C_base + (l̂₁·n̂)(C_warm − k₁·C_base)·k₂ + (l̂₂·n̂)(C_cool − k₃·C_base)·k₄
//! ```
//!
//! with `k_a = 0.9` (the paper's examples) and `k₁ … k₄ = 1` (the paper's
//! default). The paper implements the two light terms as OpenGL diffuse
//! lights, so each dot product is clamped at zero (`max(0, l̂·n̂)`): a light
//! does not subtract from surfaces facing away from it. The two lights are
//! directional and fixed in camera space, on opposite sides of the surface:
//! the warm light `l̂₁` comes from the upper left in front of the object, the
//! cool light `l̂₂ = −l̂₁` from the lower right behind it. Normals are in
//! camera space and face the viewer.

use glam::Vec3;

/// Constants of the warm/cool equation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarmCool {
    pub k_a: f32,
    pub k1: f32,
    pub k2: f32,
    pub k3: f32,
    pub k4: f32,
    /// Warm light colour (linear).
    pub warm: Vec3,
    /// Cool light colour (linear).
    pub cool: Vec3,
    /// Unit direction towards the warm light, camera space.
    pub warm_dir: Vec3,
    /// Unit direction towards the cool light, camera space.
    pub cool_dir: Vec3,
}

impl Default for WarmCool {
    fn default() -> Self {
        let warm_dir = Vec3::new(-0.5, 0.6, 0.62).normalize();
        WarmCool {
            k_a: 0.9,
            k1: 1.0,
            k2: 1.0,
            k3: 1.0,
            k4: 1.0,
            // An orange and a blue (Rademacher: "e.g., blue and orange"),
            // both light enough that k_a·C_base + the light term stays a
            // pleasant tint rather than a saturated flood.
            warm: Vec3::new(0.95, 0.62, 0.30),
            cool: Vec3::new(0.18, 0.26, 0.55),
            warm_dir,
            cool_dir: -warm_dir,
        }
    }
}

impl WarmCool {
    /// The shaded colour of a surface with base colour `base` and unit
    /// camera-space normal `n`. Not clamped: callers clamp at display.
    pub fn shade(&self, base: Vec3, n: Vec3) -> Vec3 {
        let l1 = self.warm_dir.dot(n).max(0.0);
        let l2 = self.cool_dir.dot(n).max(0.0);
        self.k_a * base + l1 * (self.warm - base * self.k1) * self.k2 + l2 * (self.cool - base * self.k3) * self.k4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).abs().max_element() < 1e-5
    }

    #[test]
    fn facing_each_light_and_neither() {
        let s = WarmCool::default();
        let base = Vec3::new(0.2, 0.5, 0.8);
        // Facing the warm light squarely: k_a·C + (C_warm − C).
        assert!(close(s.shade(base, s.warm_dir), 0.9 * base + (s.warm - base)));
        // Facing the cool light: k_a·C + (C_cool − C).
        assert!(close(s.shade(base, s.cool_dir), 0.9 * base + (s.cool - base)));
        // Perpendicular to both lights: ambient only.
        let perp = s.warm_dir.any_orthonormal_vector();
        assert!(close(s.shade(base, perp), 0.9 * base));
    }

    #[test]
    fn constants_enter_as_in_the_paper() {
        let s = WarmCool {
            k_a: 0.5,
            k1: 0.0,
            k2: 2.0,
            k3: 1.0,
            k4: 0.0,
            warm: Vec3::new(1.0, 0.5, 0.0),
            cool: Vec3::new(0.0, 0.0, 1.0),
            warm_dir: Vec3::Z,
            cool_dir: -Vec3::Z,
        };
        let base = Vec3::splat(0.4);
        // Half-way towards the warm light: 0.5·C + 0.5·(C_warm − 0·C)·2.
        let n = Vec3::new(0.0, 0.75f32.sqrt(), 0.5);
        assert!(close(s.shade(base, n), 0.5 * base + 0.5 * s.warm * 2.0));
        // k4 = 0 switches the cool light off.
        assert!(close(s.shade(base, -Vec3::Z), 0.5 * base));
    }

    #[test]
    fn k1_and_k3_scale_the_base_colour_in_each_light_term() {
        let s = WarmCool {
            k1: 0.5,
            k3: 0.5,
            ..WarmCool::default()
        };
        let base = Vec3::new(0.2, 0.5, 0.8);
        // By hand: 0.9·C + (C_warm − 0.5·C) = 0.4·C + C_warm.
        assert!(close(s.shade(base, s.warm_dir), Vec3::new(1.03, 0.82, 0.62)));
        // 0.9·C + (C_cool − 0.5·C) = 0.4·C + C_cool.
        assert!(close(s.shade(base, s.cool_dir), Vec3::new(0.26, 0.46, 0.87)));
    }
}
