//! Layout of an aggregated-ROI export, so that ROIs can also be localised
//! in ThunderSTORM as in the paper: [`roi_pages`] builds the pages, which
//! `smartagg_io::stack::write_stack` writes as a TIFF stack (16-bit pages,
//! 32-bit float if a count exceeds 65 535, exact to 2²⁴).

/// An ROI to export: its top-left sensor pixel, side and counts.
#[derive(Clone, Copy, Debug)]
pub struct RoiPage<'a> {
    /// Column of the ROI's left edge (may be negative at the sensor edge).
    pub x0: i32,
    /// Row of the ROI's top edge.
    pub y0: i32,
    /// ROI side.
    pub side: usize,
    /// Counts, row-major.
    pub counts: &'a [u32],
}

/// How exported ROIs are laid out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RoiLayout {
    /// One page per ROI of the largest ROI side (smaller ROIs padded with 0
    /// at the right and bottom); positions from ThunderSTORM are then in ROI
    /// coordinates — the caller writes the page → origin table.
    Compact,
    /// One sensor-sized page per ROI with the ROI at its place (zeros
    /// elsewhere, parts off the sensor dropped): ThunderSTORM's positions
    /// are sensor positions directly.
    Sensor {
        /// Sensor width.
        width: usize,
        /// Sensor height.
        height: usize,
    },
}

/// Builds the pages of an ROI export; returns (width, height, pages).
pub fn roi_pages(rois: &[RoiPage], layout: RoiLayout) -> (usize, usize, Vec<Vec<u32>>) {
    match layout {
        RoiLayout::Compact => {
            let side = rois.iter().map(|r| r.side).max().unwrap_or(1).max(1);
            let pages = rois
                .iter()
                .map(|r| {
                    let mut p = vec![0u32; side * side];
                    for j in 0..r.side {
                        for i in 0..r.side {
                            p[j * side + i] = r.counts.get(j * r.side + i).copied().unwrap_or(0);
                        }
                    }
                    p
                })
                .collect();
            (side, side, pages)
        }
        RoiLayout::Sensor { width, height } => {
            let pages = rois
                .iter()
                .map(|r| {
                    let mut p = vec![0u32; width * height];
                    for j in 0..r.side {
                        for i in 0..r.side {
                            let (x, y) = (r.x0 + i as i32, r.y0 + j as i32);
                            if x >= 0 && y >= 0 && (x as usize) < width && (y as usize) < height {
                                p[y as usize * width + x as usize] =
                                    r.counts.get(j * r.side + i).copied().unwrap_or(0);
                            }
                        }
                    }
                    p
                })
                .collect();
            (width, height, pages)
        }
    }
}
