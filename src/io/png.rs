//! The PNG that large meshes are drawn as inside their SVG
//! ([`super::plot::mesh_plot`]): cells painted into an RGBA image, written as
//! an 8-bit RGBA PNG (no filter, zlib by miniz_oxide, the container and its
//! CRC-32 here: a few lines, where an image crate would bring decoders and
//! formats nothing else uses).

use plotters::style::RGBColor;

/// An RGBA image that cells are painted into (transparent where none is).
pub struct Raster {
    /// Width and height in pixels (at most 4096 each).
    pub w: usize,
    pub h: usize,
    rgba: Vec<u8>,
}

impl Raster {
    pub fn new(w: usize, h: usize) -> Raster {
        let (w, h) = (w.clamp(1, 4096), h.clamp(1, 4096));
        Raster {
            w,
            h,
            rgba: vec![0; w * h * 4],
        }
    }

    /// Paints the pixels whose centres lie in the triangle `p` (pixel units,
    /// y down), edges included, so that cells tiling a body leave no gaps.
    pub fn triangle(&mut self, p: [[f64; 2]; 3], c: RGBColor) {
        let area =
            (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
        if !area.is_finite() || area == 0.0 {
            return;
        }
        let lo = |k: usize| p.iter().map(|q| q[k]).fold(f64::INFINITY, f64::min);
        let hi = |k: usize| p.iter().map(|q| q[k]).fold(f64::NEG_INFINITY, f64::max);
        let clamp = |v: f64, n: usize| (v.max(0.0) as usize).min(n);
        let (i0, i1) = (clamp(lo(0) - 0.5, self.w), clamp(hi(0) + 0.5, self.w));
        let (j0, j1) = (clamp(lo(1) - 0.5, self.h), clamp(hi(1) + 0.5, self.h));
        let sign = area.signum();
        let edge = |a: [f64; 2], b: [f64; 2], x: f64, y: f64| {
            sign * ((b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]))
        };
        for j in j0..j1 {
            let y = j as f64 + 0.5;
            for i in i0..i1 {
                let x = i as f64 + 0.5;
                if edge(p[0], p[1], x, y) >= 0.0
                    && edge(p[1], p[2], x, y) >= 0.0
                    && edge(p[2], p[0], x, y) >= 0.0
                {
                    let k = 4 * (j * self.w + i);
                    self.rgba[k..k + 4].copy_from_slice(&[c.0, c.1, c.2, 255]);
                }
            }
        }
    }

    /// The image as a PNG file: 8-bit RGBA, no filter, zlib by miniz_oxide.
    pub fn png(&self) -> Vec<u8> {
        let mut raw = Vec::with_capacity((self.w * 4 + 1) * self.h);
        for row in self.rgba.chunks(self.w * 4) {
            raw.push(0);
            raw.extend_from_slice(row);
        }
        let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
        let mut header = Vec::with_capacity(13);
        header.extend_from_slice(&(self.w as u32).to_be_bytes());
        header.extend_from_slice(&(self.h as u32).to_be_bytes());
        header.extend_from_slice(&[8, 6, 0, 0, 0]);
        png_chunk(&mut out, b"IHDR", &header);
        png_chunk(
            &mut out,
            b"IDAT",
            &miniz_oxide::deflate::compress_to_vec_zlib(&raw, 6),
        );
        png_chunk(&mut out, b"IEND", &[]);
        out
    }
}

/// One PNG chunk: length, type, data, CRC-32 of type and data.
fn png_chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    let crc = crc32(kind.iter().chain(data));
    out.extend_from_slice(&crc.to_be_bytes());
}

/// CRC-32 (IEEE, reflected, as PNG and zip use it), bit by bit: the images are
/// small enough that a table buys nothing.
pub(crate) fn crc32<'a>(bytes: impl Iterator<Item = &'a u8>) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                0xEDB8_8320 ^ (crc >> 1)
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_matches_the_check_value() {
        assert_eq!(crc32(b"123456789".iter()), 0xCBF4_3926);
        assert_eq!(crc32(b"".iter()), 0);
    }
}
