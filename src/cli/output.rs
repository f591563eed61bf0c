//! Where the commands' output goes.
//!
//! - [`Output`]: an `-o` argument, a file or `-` (standard output). Files are
//!   written by `quadtex_io`'s rules (atomic replacement; symbolic links
//!   followed and kept; devices and FIFOs written in place).
//! - [`Text`]: the writer every report and summary goes through, so that a
//!   closed pipe (`quadtex info t.qtx | head -1`) is an error naming
//!   standard output instead of a panic. When standard output carries data
//!   (`-o -`), summaries go to standard error instead ([`Output::text`]).

use std::ffi::OsString;
use std::fmt;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use quadtex_core::QuadTree;
use quadtex_io::{ImageFormat, LinearImage};

use super::Result;

/// How errors name standard output.
pub const STDOUT: &str = "standard output";

/// An `-o` argument: `-` for standard output, anything else a file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Output {
    /// `-o -`.
    Stdout,
    /// `-o FILE`.
    File(PathBuf),
}

impl From<OsString> for Output {
    fn from(text: OsString) -> Output {
        if text == "-" {
            Output::Stdout
        } else {
            Output::File(text.into())
        }
    }
}

impl fmt::Display for Output {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Output::Stdout => f.write_str(STDOUT),
            Output::File(path) => write!(f, "{}", path.display()),
        }
    }
}

/// `--format`: the image format, for `-o -` or a name without `.png`/`.exr`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FormatArg {
    /// PNG: sRGB, 8 bits per channel, straight alpha.
    Png,
    /// OpenEXR: linear, 32-bit float, premultiplied alpha.
    Exr,
}

impl From<FormatArg> for ImageFormat {
    fn from(f: FormatArg) -> ImageFormat {
        match f {
            FormatArg::Png => ImageFormat::Png,
            FormatArg::Exr => ImageFormat::Exr,
        }
    }
}

impl Output {
    /// Whether this is standard output.
    pub fn is_stdout(&self) -> bool {
        *self == Output::Stdout
    }

    /// The image format to write: `--format` if given (it must agree with a
    /// `.png`/`.exr` extension), else the extension, else PNG for `-o -`.
    pub fn image_format(&self, flag: Option<FormatArg>) -> Result<ImageFormat> {
        let by_name = match self {
            Output::Stdout => None,
            Output::File(path) => ImageFormat::from_path(path),
        };
        match (flag.map(ImageFormat::from), by_name) {
            (Some(f), Some(n)) if f != n => Err(format!(
                "{self}: --format {} contradicts the .{} extension",
                f.extension(),
                n.extension()
            )
            .into()),
            (Some(f), _) => Ok(f),
            (None, Some(n)) => Ok(n),
            (None, None) if self.is_stdout() => Ok(ImageFormat::Png),
            (None, None) => Err(format!(
                "{self}: output must end in .png or .exr (or give --format png|exr)"
            )
            .into()),
        }
    }

    /// Writes `image` as `format`.
    pub fn save_image(&self, image: &LinearImage, format: ImageFormat) -> Result<()> {
        match self {
            Output::Stdout => {
                quadtex_io::write_image(&mut io::stdout().lock(), Path::new(STDOUT), image, format)?
            }
            Output::File(path) => quadtex_io::save_image_as(path, image, format)?,
        }
        Ok(())
    }

    /// Writes `tree` as a `.qtx` file.
    pub fn write_qtx(&self, tree: &QuadTree, source: Option<(u32, u32)>) -> Result<()> {
        match self {
            Output::Stdout => {
                quadtex_io::write_qtx_to(&mut io::stdout().lock(), Path::new(STDOUT), tree, source)?
            }
            Output::File(path) => quadtex_io::write_qtx(path, tree, source)?,
        }
        Ok(())
    }

    /// Where summaries go: standard error when standard output carries the
    /// data, standard output otherwise.
    pub fn text(&self) -> Text {
        if self.is_stdout() {
            Text::stderr()
        } else {
            Text::stdout()
        }
    }
}

/// A text writer whose errors name the stream (`standard output: Broken
/// pipe`), for reports and summaries; use with `writeln!(…)?`.
pub struct Text {
    inner: Box<dyn Write>,
    name: &'static str,
}

impl Text {
    /// Standard output (line-buffered, so an error shows at the line).
    pub fn stdout() -> Text {
        Text {
            inner: Box::new(io::stdout()),
            name: STDOUT,
        }
    }

    /// Standard error.
    pub fn stderr() -> Text {
        Text {
            inner: Box::new(io::stderr()),
            name: "standard error",
        }
    }

    fn named(&self, e: io::Error) -> io::Error {
        io::Error::new(e.kind(), format!("{}: {e}", self.name))
    }
}

impl Write for Text {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.inner.write(buf).map_err(|e| self.named(e))
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        self.inner.write_all(buf).map_err(|e| self.named(e))
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush().map_err(|e| self.named(e))
    }
}

/// `--format` of `render`, `demo` and `sample`.
#[derive(Debug, clap::Args)]
pub struct FormatFlag {
    /// Image format: needed only when `-o` is `-` (default png) or a name
    /// without .png/.exr (a FIFO, a device); must agree with a .png/.exr
    /// extension.
    #[arg(long, value_name = "png|exr", value_enum)]
    pub format: Option<FormatArg>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dash_is_stdout_and_the_format_rule() {
        let dash = Output::from(OsString::from("-"));
        assert!(dash.is_stdout());
        assert_eq!(dash.to_string(), STDOUT);
        assert_eq!(dash.image_format(None).unwrap(), ImageFormat::Png);
        assert_eq!(
            dash.image_format(Some(FormatArg::Exr)).unwrap(),
            ImageFormat::Exr
        );
        let png = Output::from(OsString::from("a/b.PNG"));
        assert_eq!(png.image_format(None).unwrap(), ImageFormat::Png);
        assert_eq!(
            png.image_format(Some(FormatArg::Exr))
                .unwrap_err()
                .to_string(),
            "a/b.PNG: --format exr contradicts the .png extension"
        );
        let fifo = Output::from(OsString::from("/tmp/fifo"));
        assert!(
            fifo.image_format(None)
                .unwrap_err()
                .to_string()
                .contains("--format png|exr")
        );
        assert_eq!(
            fifo.image_format(Some(FormatArg::Exr)).unwrap(),
            ImageFormat::Exr
        );
    }
}
