//! Host files through ARM semihosting (`BKPT 0xAB`): the QEMU board's way to read recorded frames
//! and write results. Only built for the Cortex-M target; every `unsafe` of the crate is here.
//!
//! With QEMU's `-semihosting-config enable=on,target=native`, paths are host paths relative to
//! QEMU's working directory.

use core::fmt;

use cortex_m_semihosting::{nr, syscall, syscall1};

/// Longest path (in bytes, without the terminating NUL) [`HostFile::open`] accepts.
pub const MAX_PATH: usize = 255;

/// A failed semihosting call.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
#[non_exhaustive]
pub enum SemihostingError {
    /// The path is longer than [`MAX_PATH`] or holds a NUL byte.
    BadPath,
    /// `SYS_OPEN` failed (no such file, no permission).
    Open,
    /// `SYS_FLEN` failed.
    Length,
    /// `SYS_READ` returned fewer bytes than asked (end of file or an error).
    ShortRead {
        /// Bytes asked for.
        wanted: usize,
        /// Bytes not read.
        missing: usize,
    },
    /// `SYS_WRITE` wrote fewer bytes than given.
    ShortWrite,
    /// `SYS_GET_CMDLINE` failed or returned text that is not UTF-8.
    CommandLine,
}

impl fmt::Display for SemihostingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::BadPath => write!(f, "path too long or holding a NUL byte"),
            Self::Open => write!(f, "SYS_OPEN failed"),
            Self::Length => write!(f, "SYS_FLEN failed"),
            Self::ShortRead { wanted, missing } => {
                write!(f, "SYS_READ left {missing} of {wanted} bytes unread")
            }
            Self::ShortWrite => write!(f, "SYS_WRITE did not write everything"),
            Self::CommandLine => write!(f, "SYS_GET_CMDLINE failed"),
        }
    }
}

impl core::error::Error for SemihostingError {}

impl embedded_io::Error for SemihostingError {
    fn kind(&self) -> embedded_io::ErrorKind {
        embedded_io::ErrorKind::Other
    }
}

/// How a host file is opened (the `fopen` modes of the semihosting spec, binary).
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum Mode {
    /// `"rb"`: read an existing file.
    Read,
    /// `"wb"`: create or truncate, then write.
    WriteTruncate,
}

/// An open host file, closed on drop.
#[derive(Debug)]
pub struct HostFile {
    handle: usize,
}

impl HostFile {
    /// Opens the host file at `path`.
    ///
    /// # Errors
    /// [`SemihostingError::BadPath`] or [`SemihostingError::Open`].
    pub fn open(path: &str, mode: Mode) -> Result<Self, SemihostingError> {
        // The call wants a NUL-terminated string and its length without the NUL.
        let mut z = [0u8; MAX_PATH + 1];
        let dst = z.get_mut(..path.len()).ok_or(SemihostingError::BadPath)?;
        if path.as_bytes().contains(&0) {
            return Err(SemihostingError::BadPath);
        }
        dst.copy_from_slice(path.as_bytes());
        let mode = match mode {
            Mode::Read => nr::open::R_BINARY,
            Mode::WriteTruncate => nr::open::W_TRUNC_BINARY,
        };
        // SAFETY: SYS_OPEN reads `path.len()` bytes plus the NUL from `z`, which outlives the call.
        let handle = unsafe { syscall!(OPEN, z.as_ptr(), mode, path.len()) };
        if handle == usize::MAX {
            return Err(SemihostingError::Open);
        }
        Ok(Self { handle })
    }

    /// The file's length in bytes.
    ///
    /// # Errors
    /// [`SemihostingError::Length`].
    pub fn len(&self) -> Result<usize, SemihostingError> {
        // SAFETY: SYS_FLEN only reads the argument block.
        let n = unsafe { syscall!(FLEN, self.handle) };
        // The call returns -1 on error.
        if n == usize::MAX { Err(SemihostingError::Length) } else { Ok(n) }
    }

    /// Whether the file is empty.
    ///
    /// # Errors
    /// As [`HostFile::len`].
    pub fn is_empty(&self) -> Result<bool, SemihostingError> {
        self.len().map(|n| n == 0)
    }

    /// Reads exactly `buf.len()` bytes from the current position.
    ///
    /// # Errors
    /// [`SemihostingError::ShortRead`] at end of file or on a host error.
    pub fn read_exact(&mut self, buf: &mut [u8]) -> Result<(), SemihostingError> {
        // SAFETY: SYS_READ writes at most `buf.len()` bytes into `buf`, borrowed mutably for the
        // duration of the call.
        let missing = unsafe { syscall!(READ, self.handle, buf.as_mut_ptr(), buf.len()) };
        if missing != 0 {
            return Err(SemihostingError::ShortRead { wanted: buf.len(), missing });
        }
        Ok(())
    }

    /// Reads up to `buf.len()` bytes from the current position; returns how many (0 at the end
    /// of the file).
    ///
    /// # Errors
    /// [`SemihostingError::ShortRead`] when the call reports more missing bytes than asked for
    /// (a host error).
    pub fn read_some(&mut self, buf: &mut [u8]) -> Result<usize, SemihostingError> {
        // SAFETY: as in `read_exact`.
        let missing = unsafe { syscall!(READ, self.handle, buf.as_mut_ptr(), buf.len()) };
        buf.len()
            .checked_sub(missing)
            .ok_or(SemihostingError::ShortRead { wanted: buf.len(), missing })
    }

    /// Writes all of `bytes`.
    ///
    /// # Errors
    /// [`SemihostingError::ShortWrite`].
    pub fn write_all(&mut self, bytes: &[u8]) -> Result<(), SemihostingError> {
        // SAFETY: SYS_WRITE reads `bytes.len()` bytes from `bytes`, which outlives the call.
        let missing = unsafe { syscall!(WRITE, self.handle, bytes.as_ptr(), bytes.len()) };
        if missing != 0 {
            return Err(SemihostingError::ShortWrite);
        }
        Ok(())
    }
}

impl Drop for HostFile {
    fn drop(&mut self) {
        // SAFETY: SYS_CLOSE only reads the argument block; the handle is not used again.
        // A failed close of a file already read or written has nothing left to report.
        let _ = unsafe { syscall!(CLOSE, self.handle) };
    }
}

/// The program's command line from the host (QEMU: the kernel path followed by `-append`'s text),
/// written into `buf`.
///
/// # Errors
/// [`SemihostingError::CommandLine`] when the host reports an error (a line longer than `buf`)
/// or the text is not UTF-8.
pub fn command_line(buf: &mut [u8]) -> Result<&str, SemihostingError> {
    // The argument block is in/out: the host overwrites word 1 with the length it wrote.
    let mut block = [buf.as_mut_ptr() as usize, buf.len()];
    // SAFETY: the host writes at most `buf.len()` bytes into `buf` and one word into `block`, both
    // borrowed mutably for the duration of the call.
    let status = unsafe { syscall1(nr::GET_CMDLINE, block.as_mut_ptr() as usize) };
    if status != 0 {
        return Err(SemihostingError::CommandLine);
    }
    let [_, len] = block;
    let text = buf.get(..len).ok_or(SemihostingError::CommandLine)?;
    core::str::from_utf8(text).map_err(|_| SemihostingError::CommandLine)
}

impl embedded_io::ErrorType for HostFile {
    type Error = SemihostingError;
}

/// A host file as a byte stream (what [`crate::commands::LinkCommands`] reads the QEMU board's
/// received bytes from).
impl embedded_io::Read for HostFile {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        self.read_some(buf)
    }
}
