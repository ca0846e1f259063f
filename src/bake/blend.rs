// SPDX-License-Identifier: MIT OR Apache-2.0
//! Blend modes: the Rust twin of `wgsl/shared/blend.wgsl` (W3C Compositing and Blending Level 1,
//! separable modes; "add" is linear dodge), applied in linear light. Ids must match the WGSL constants.

use crate::io::job::BlendMode;

impl BlendMode {
    fn channel(self, cb: f32, cs: f32) -> f32 {
        match self {
            BlendMode::Normal => cs,
            BlendMode::Multiply => cb * cs,
            BlendMode::Screen => cb + cs - cb * cs,
            BlendMode::Overlay => {
                if cb <= 0.5 {
                    2.0 * cb * cs
                } else {
                    let s = 2.0 * cb - 1.0;
                    cs + s - cs * s
                }
            }
            BlendMode::Add => (cb + cs).min(1.0),
            BlendMode::Darken => cb.min(cs),
            BlendMode::Lighten => cb.max(cs),
            BlendMode::ColorDodge => {
                if cb <= 0.0 {
                    0.0
                } else if cs >= 1.0 {
                    1.0
                } else {
                    (cb / (1.0 - cs)).min(1.0)
                }
            }
            BlendMode::ColorBurn => {
                if cb >= 1.0 {
                    1.0
                } else if cs <= 0.0 {
                    0.0
                } else {
                    1.0 - ((1.0 - cb) / cs).min(1.0)
                }
            }
        }
    }

    /// Composes premultiplied `src` over straight-alpha `dst`, returning straight alpha.
    pub fn blend(self, dst: [f32; 4], src: [f32; 4]) -> [f32; 4] {
        let a_s = src[3];
        if a_s <= 0.0 {
            return dst;
        }
        let ab = dst[3];
        let ao = a_s + ab * (1.0 - a_s);
        if ao <= 0.0 {
            return [0.0; 4];
        }
        let mut out = [0.0; 4];
        for k in 0..3 {
            let cs = src[k] / a_s;
            let cb = dst[k];
            let co =
                (1.0 - a_s) * ab * cb + (1.0 - ab) * a_s * cs + a_s * ab * self.channel(cb, cs);
            out[k] = co / ao;
        }
        out[3] = ao;
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn opaque_normal_replaces_and_transparent_keeps() {
        let dst = [0.2, 0.4, 0.6, 1.0];
        assert_eq!(
            BlendMode::Normal.blend(dst, [0.9, 0.1, 0.0, 1.0]),
            [0.9, 0.1, 0.0, 1.0]
        );
        for m in BlendMode::ALL {
            assert_eq!(m.blend(dst, [0.0; 4]), dst, "{m:?}");
        }
    }

    #[test]
    fn known_values() {
        let dst = [0.25, 0.75, 0.5, 1.0];
        let src = [0.5, 0.5, 0.5, 1.0];
        let close = |a: [f32; 4], b: [f32; 4]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6);
        assert!(close(
            BlendMode::Multiply.blend(dst, src),
            [0.125, 0.375, 0.25, 1.0]
        ));
        assert!(close(
            BlendMode::Screen.blend(dst, src),
            [0.625, 0.875, 0.75, 1.0]
        ));
        assert!(close(
            BlendMode::Overlay.blend(dst, src),
            [0.25, 0.75, 0.5, 1.0]
        ));
        assert!(close(BlendMode::Add.blend(dst, src), [0.75, 1.0, 1.0, 1.0]));
        assert!(close(
            BlendMode::ColorDodge.blend(dst, src),
            [0.5, 1.0, 1.0, 1.0]
        ));
        assert!(close(
            BlendMode::ColorBurn.blend(dst, src),
            [0.0, 0.5, 0.0, 1.0]
        ));
        // Half-transparent normal: halfway.
        assert!(close(
            BlendMode::Normal.blend(dst, [0.25, 0.25, 0.25, 0.5]),
            [0.375, 0.625, 0.5, 1.0]
        ));
    }

    #[test]
    fn parse_accepts_spellings_and_rejects_unknown() {
        assert_eq!(
            BlendMode::parse("Color Dodge").unwrap(),
            BlendMode::ColorDodge
        );
        assert_eq!(
            BlendMode::parse("color-burn").unwrap(),
            BlendMode::ColorBurn
        );
        assert!(BlendMode::parse("hue").unwrap_err().contains("color_burn"));
    }
}
