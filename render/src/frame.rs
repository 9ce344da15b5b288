//! One rendered camera frame and its encodings.

use crate::error::{RenderError, Result};

/// One camera's image at one instant: colour and depth, the same size, row-major, the top
/// row first (pixel `(u, v)` at index `v * width + u`, the convention of [`crate::camera`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Frame {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// `width * height * 3` bytes, RGB8 (no gamma applied: the shaded albedo values).
    pub rgb: Vec<u8>,
    /// `width * height` depths, metres, along the optical axis: the optical-frame z of the
    /// surface a pixel sees (what a depth camera and ROS REP 118 report), not the length of
    /// the ray to it. `0.0` where the pixel sees nothing (sky, or beyond [`crate::FAR_M`]).
    pub depth_m: Vec<f32>,
}

impl Frame {
    /// The colour of pixel `(u, v)`, `None` outside the image.
    pub fn rgb_at(&self, u: u32, v: u32) -> Option<[u8; 3]> {
        let i = self.index(u, v)? * 3;
        Some([self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]])
    }

    /// The depth of pixel `(u, v)`, metres along the optical axis (0 = no hit), `None`
    /// outside the image.
    pub fn depth_at(&self, u: u32, v: u32) -> Option<f32> {
        Some(self.depth_m[self.index(u, v)?])
    }

    fn index(&self, u: u32, v: u32) -> Option<usize> {
        (u < self.width && v < self.height).then(|| v as usize * self.width as usize + u as usize)
    }

    /// The colour image as an 8-bit RGB PNG (fast deflate: frames are encoded at camera
    /// rates; the bytes are deterministic).
    ///
    /// # Errors
    ///
    /// [`RenderError::Encode`] if the encoder fails (it does not for a well-formed frame).
    pub fn rgb_png(&self) -> Result<Vec<u8>> {
        png_bytes(self.width, self.height, png::ColorType::Rgb, png::BitDepth::Eight, &self.rgb)
    }

    /// The colour image as a baseline JPEG of `quality` 1..=100 (4:2:0 chroma, the
    /// encoder's default).
    ///
    /// # Errors
    ///
    /// [`RenderError::Encode`] for a quality outside 1..=100.
    pub fn rgb_jpeg(&self, quality: u8) -> Result<Vec<u8>> {
        let fail = |reason: String| RenderError::Encode { format: "JPEG", reason };
        if !(1..=100).contains(&quality) {
            return Err(fail(format!("quality {quality} is outside 1..=100")));
        }
        // MAX_SIDE_PX (4096) fits JPEG's 16-bit sizes.
        let (w, h) = (u16::try_from(self.width), u16::try_from(self.height));
        let (Ok(w), Ok(h)) = (w, h) else {
            return Err(fail(format!("{}x{} is larger than JPEG's 65535 pixels a side", self.width, self.height)));
        };
        let mut out = Vec::new();
        jpeg_encoder::Encoder::new(&mut out, quality)
            .encode(&self.rgb, w, h, jpeg_encoder::ColorType::Rgb)
            .map_err(|e| fail(e.to_string()))?;
        Ok(out)
    }

    /// The depth image as a 16-bit grayscale PNG of millimetres (ROS `16UC1` depth):
    /// rounded, saturating at 65535 (65.5 m), 0 where there is no hit.
    ///
    /// # Errors
    ///
    /// [`RenderError::Encode`] if the encoder fails (it does not for a well-formed frame).
    pub fn depth_png_mm(&self) -> Result<Vec<u8>> {
        // PNG stores 16-bit samples big-endian.
        let samples: Vec<u8> = self.depth_m.iter().flat_map(|&d| millimetres(d).to_be_bytes()).collect();
        png_bytes(self.width, self.height, png::ColorType::Grayscale, png::BitDepth::Sixteen, &samples)
    }

    /// The depth image as raw 16-bit millimetres, little-endian, row-major (ROS and
    /// Foxglove `RawImage` encoding `16UC1`), rounded and saturating as
    /// [`Frame::depth_png_mm`].
    pub fn depth_mm_le(&self) -> Vec<u8> {
        self.depth_m.iter().flat_map(|&d| millimetres(d).to_le_bytes()).collect()
    }

    /// The depth image as raw float32 metres, little-endian, row-major (ROS `32FC1` with
    /// `is_bigendian = 0`; Foxglove `RawImage` encoding `32FC1`).
    pub fn depth_f32_le(&self) -> Vec<u8> {
        self.depth_m.iter().flat_map(|d| d.to_le_bytes()).collect()
    }
}

/// A depth in metres as `16UC1` millimetres: rounded, saturating at 65535, 0 for no hit.
fn millimetres(d: f32) -> u16 {
    if d.is_finite() && d > 0.0 { (f64::from(d) * 1000.0).round().min(65535.0) as u16 } else { 0 }
}

fn png_bytes(width: u32, height: u32, color: png::ColorType, depth: png::BitDepth, data: &[u8]) -> Result<Vec<u8>> {
    let fail = |e: png::EncodingError| RenderError::Encode { format: "PNG", reason: e.to_string() };
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, width, height);
    encoder.set_color(color);
    encoder.set_depth(depth);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().map_err(fail)?;
    writer.write_image_data(data).map_err(fail)?;
    writer.finish().map_err(fail)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> Frame {
        Frame { width: 2, height: 1, rgb: vec![1, 2, 3, 4, 5, 6], depth_m: vec![0.0, 70.0] }
    }

    #[test]
    fn depth_png_saturates_and_keeps_no_hit_at_zero() {
        let png = frame().depth_png_mm().expect("encodes");
        let mut reader = png::Decoder::new(std::io::Cursor::new(png)).read_info().expect("decodes");
        let mut buf = vec![0; reader.output_buffer_size().expect("size")];
        reader.next_frame(&mut buf).expect("frame");
        assert_eq!(buf, [0, 0, 255, 255]);
    }

    #[test]
    fn jpeg_quality_is_checked() {
        assert!(frame().rgb_jpeg(0).is_err());
        assert!(frame().rgb_jpeg(90).expect("encodes").starts_with(&[0xFF, 0xD8]));
    }

    #[test]
    fn raw_depth_is_little_endian_f32() {
        assert_eq!(frame().depth_f32_le()[4..], 70.0f32.to_le_bytes());
    }
}
