//! Pixels for matseg: float planes and RGB images, colour channels (RGB/HSV)
//! on 8-bit levels with their counts and histograms,
//! threshold ramps, Gaussian blur, mip-pyramid resampling, image I/O and the
//! bounded, decode-once photo library every generator draws from; the CIE
//! L*a*b* conversion; photo fingerprints; the progress reports of long
//! jobs and the device a model runs on. What models make of pixels
//! (descriptor maps, similarity, clustering, tracking) is matseg-query's.

#![warn(missing_docs)]

pub mod bilinear;
pub mod blur;
pub mod budget;
pub mod channel;
pub mod channel_rows;
pub mod coverage;
pub mod device;
pub mod fingerprint;
pub mod io;
pub mod lab;
pub mod levels;
pub mod library;
pub mod licence;
pub mod mirrors;
pub mod outputs;
pub mod plane;
pub mod progress;
pub mod ramp;
pub mod resample;
pub mod rgb;
pub mod sparse;
pub mod sync;

pub use blur::{gaussian_blur, gaussian_blur_covered, CoveredBlur};
pub use budget::{ByteLru, MemoryBudget};
pub use channel::Channel;
pub use channel_rows::{ChannelRows, WindowRows};
pub use coverage::Coverage;
pub use io::ImageIoError;
pub use levels::{level_values, ChannelWindow, LevelCounts, LevelHistogram, LevelTable};
pub use library::{licence_of, LibraryError, Photo, PhotoLibrary, ScanReport, SkippedFile};
pub use licence::{licence_family, LicenceFilter};
pub use mirrors::Mirrors;
pub use plane::Plane;
pub use ramp::Ramp;
pub use resample::{CropWindow, Pyramid};
pub use sparse::SparsePlane;
