//! Portable float map (PFM) images: radiance in physical units, 32-bit float, no
//! dependency. Grey (`Pf`, 1 channel) or colour (`PF`, 3 channels); little-endian (scale
//! −1); rows stored bottom to top as the format requires, so readers show the image upright.

use std::io::{self, Write};
use std::path::Path;

/// Writes a 1- or 3-channel image (`channels[c][y·width + x]`, top row first) as PFM.
pub fn write_pfm(path: &Path, width: usize, height: usize, channels: &[&[f64]]) -> io::Result<()> {
    let nc = channels.len();
    if !(nc == 1 || nc == 3) || channels.iter().any(|c| c.len() != width * height) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("PFM needs 1 or 3 channels of {width}x{height} pixels"),
        ));
    }
    let mut out = Vec::with_capacity(32 + width * height * nc * 4);
    write!(
        out,
        "{}\n{width} {height}\n-1.0\n",
        if nc == 3 { "PF" } else { "Pf" }
    )?;
    for y in (0..height).rev() {
        for x in 0..width {
            for c in channels {
                out.extend_from_slice(&(c[y * width + x] as f32).to_le_bytes());
            }
        }
    }
    std::fs::write(path, out)
}

/// Reads a PFM written by [`write_pfm`] (or any little- or big-endian PFM): width, height
/// and the channels, top row first.
pub fn read_pfm(path: &Path) -> io::Result<(usize, usize, Vec<Vec<f64>>)> {
    let bytes = std::fs::read(path)?;
    let bad = |m: &str| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{}: {m}", path.display()),
        )
    };
    // Header: three whitespace-terminated tokens lines.
    let mut fields = Vec::new();
    let mut pos = 0;
    while fields.len() < 4 && pos < bytes.len() {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        fields.push(String::from_utf8_lossy(&bytes[start..pos]).into_owned());
    }
    pos += 1;
    if fields.len() < 4 {
        return Err(bad("truncated header"));
    }
    let nc = match fields[0].as_str() {
        "PF" => 3,
        "Pf" => 1,
        _ => return Err(bad("not a PFM file")),
    };
    let w: usize = fields[1].parse().map_err(|_| bad("bad width"))?;
    let h: usize = fields[2].parse().map_err(|_| bad("bad height"))?;
    let scale: f64 = fields[3].parse().map_err(|_| bad("bad scale"))?;
    let data = bytes.get(pos..).ok_or_else(|| bad("no data"))?;
    if data.len() < w * h * nc * 4 {
        return Err(bad("truncated data"));
    }
    let mut ch = vec![vec![0.0; w * h]; nc];
    for (k, chunk) in data.chunks_exact(4).take(w * h * nc).enumerate() {
        let b = [chunk[0], chunk[1], chunk[2], chunk[3]];
        let v = if scale < 0.0 {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        };
        let c = k % nc;
        let p = k / nc;
        let (x, yb) = (p % w, p / w);
        ch[c][(h - 1 - yb) * w + x] = f64::from(v);
    }
    Ok((w, h, ch))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pfm_round_trip_keeps_orientation_and_channels() {
        let dir = std::env::temp_dir().join(format!("scatterbench-pfm-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (w, h) = (3, 2);
        let r: Vec<f64> = (0..6).map(|i| i as f64).collect();
        let g: Vec<f64> = (0..6).map(|i| 10.0 + i as f64).collect();
        let b: Vec<f64> = (0..6).map(|i| 0.5 * i as f64).collect();
        write_pfm(&dir.join("c.pfm"), w, h, &[&r, &g, &b]).unwrap();
        let (w2, h2, ch) = read_pfm(&dir.join("c.pfm")).unwrap();
        assert_eq!((w2, h2), (w, h));
        assert_eq!(ch, vec![r.clone(), g, b]);
        write_pfm(&dir.join("m.pfm"), w, h, &[&r]).unwrap();
        assert_eq!(read_pfm(&dir.join("m.pfm")).unwrap().2, vec![r.clone()]);
        assert!(write_pfm(&dir.join("x.pfm"), w, h, &[&r, &r]).is_err());
        std::fs::remove_dir_all(&dir).ok();
    }
}
