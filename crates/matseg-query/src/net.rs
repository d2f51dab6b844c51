//! A trained net as the queries use it, whichever engine runs it (pure
//! Rust on the CPU, libtorch on CUDA): a photo's descriptors on the net's
//! coarse grid, or at every pixel.

use crate::coarse::CoarseDescriptors;
use crate::descriptor::{resize_channels, Comparison, DescriptorMap, DescriptorModel};
use image::RgbImage;
use rayon::prelude::*;
use std::borrow::Cow;

/// A photo's descriptors on a net's stride-4 grid, not yet normalised:
/// `dim` values per cell, cell by cell, row by row.
#[derive(Clone, Debug, PartialEq)]
pub struct PhotoGrid {
    /// Channels per cell, cell by cell, row by row.
    pub values: Vec<f32>,
    /// Cells across.
    pub width: usize,
    /// Cells down.
    pub height: usize,
    /// Channels.
    pub dim: usize,
}

impl PhotoGrid {
    /// The descriptor map of a `width x height` photo: the grid resized
    /// bilinearly to the photo (half-pixel centres) and each pixel
    /// normalised.
    pub fn pixel_map(&self, width: usize, height: usize) -> DescriptorMap {
        let mut data = resize_channels(
            Cow::Borrowed(&self.values),
            (self.width, self.height),
            self.dim,
            (width, height),
        );
        data.par_chunks_mut(self.dim).for_each(normalise);
        DescriptorMap {
            width,
            height,
            dim: self.dim,
            data,
        }
    }

    /// The grid's cells normalised, as coarse descriptors of a `width x
    /// height` photo.
    pub fn into_coarse(mut self, width: usize, height: usize) -> CoarseDescriptors {
        self.values.par_chunks_mut(self.dim).for_each(normalise);
        CoarseDescriptors {
            grid: DescriptorMap {
                width: self.width,
                height: self.height,
                dim: self.dim,
                data: self.values,
            },
            width,
            height,
        }
    }
}

/// Scales `v` to unit length (a norm below 1e-12 taken as 1e-12).
fn normalise(v: &mut [f32]) {
    let norm = v.iter().map(|x| x * x).sum::<f32>().sqrt().max(1e-12);
    v.iter_mut().for_each(|x| *x /= norm);
}

/// A trained net that describes photos.
pub trait DescriptorNet: Send + Sync {
    /// Channels of its descriptors.
    fn output_dim(&self) -> usize;

    /// The longest side it sees a photo at (`None`: as it is).
    fn inference_side(&self) -> Option<u32>;

    /// Makes it see photos at a longer side of `main` (`None`: as they
    /// are) and add the unit descriptors of each of `extra` sides.
    fn set_inference_sides(&mut self, main: Option<u32>, extra: Vec<u32>);

    /// `photo`'s grid at its sizes, merged, not yet normalised: the part
    /// of a description that needs the net ([`PhotoGrid::pixel_map`] and
    /// [`PhotoGrid::into_coarse`] make the rest).
    fn photo_grid(&self, photo: &RgbImage) -> PhotoGrid;

    /// The net alone on `photo` at its own size, whose sides are
    /// multiples of 32 (no shrinking, one size): its grid, not yet
    /// normalised. What an exported copy of the net must reproduce.
    fn own_size_grid(&self, photo: &RgbImage) -> PhotoGrid;

    /// Unit descriptors of `photo` on the net's grid at one size, the
    /// photo shrunk to fit a longer side of `side` pixels by area
    /// averaging: the fast path of video tracking, one pass a frame.
    fn describe_frame(&self, photo: &RgbImage, side: u32) -> CoarseDescriptors;

    /// Unit descriptors of `photo` on the net's grid, for querying in
    /// photo pixels: what `matseg segment` and a click use.
    fn describe_coarse(&self, photo: &RgbImage) -> CoarseDescriptors {
        self.photo_grid(photo)
            .into_coarse(photo.width() as usize, photo.height() as usize)
    }
}

/// A trained net under a name, as an evaluated model: unit descriptors of
/// every pixel, compared by cosine.
pub struct NamedNet {
    name: String,
    net: Box<dyn DescriptorNet>,
}

impl NamedNet {
    /// `net` under the name `name` in result tables.
    pub fn new(name: impl Into<String>, net: Box<dyn DescriptorNet>) -> Self {
        Self {
            name: name.into(),
            net,
        }
    }

    /// The net.
    pub fn net(&self) -> &dyn DescriptorNet {
        self.net.as_ref()
    }

    /// The net, to change its settings before it is used.
    pub fn net_mut(&mut self) -> &mut dyn DescriptorNet {
        self.net.as_mut()
    }
}

impl DescriptorModel for NamedNet {
    fn name(&self) -> &str {
        &self.name
    }

    fn comparison(&self) -> Comparison {
        Comparison::Cosine
    }

    fn describe(&self, image: &RgbImage) -> DescriptorMap {
        self.net
            .photo_grid(image)
            .pixel_map(image.width() as usize, image.height() as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grid_becomes_unit_descriptors_at_either_size() {
        // 2x1 cells of 2 channels.
        let grid = PhotoGrid {
            values: vec![3.0, 4.0, 0.0, 2.0],
            width: 2,
            height: 1,
            dim: 2,
        };
        let coarse = grid.clone().into_coarse(8, 4);
        assert_eq!(coarse.grid.data, [0.6, 0.8, 0.0, 1.0]);
        assert_eq!((coarse.width, coarse.height), (8, 4));
        let map = grid.pixel_map(4, 1);
        // Pixel centres at 0.5, 1.5, 2.5, 3.5 over cells of two pixels:
        // the outer ones are the cells', the inner ones mixed 3:1.
        assert_eq!(&map.data[..2], [0.6, 0.8]);
        assert_eq!(&map.data[6..], [0.0, 1.0]);
        let mixed: [f32; 2] = [0.75 * 3.0, 0.75 * 4.0 + 0.25 * 2.0];
        let norm = (mixed[0] * mixed[0] + mixed[1] * mixed[1]).sqrt();
        assert!((map.data[2] - mixed[0] / norm).abs() < 1e-6);
        assert!((map.data[3] - mixed[1] / norm).abs() < 1e-6);
    }
}
