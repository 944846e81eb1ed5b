//! Byte transports for the Hannes link. The link only needs "open a duplex
//! byte stream with a read timeout", so a USB serial adapter, a Bluetooth
//! RFCOMM tty (`/dev/rfcomm0`), a udev symlink (`/dev/serial/by-id/...`) or a
//! pseudo-terminal all fit behind [`Connector`].

use std::io::{self, Read, Write};
use std::path::PathBuf;
use std::time::Duration;

/// An open byte stream. `read` returns `ErrorKind::TimedOut` (or
/// `WouldBlock`) when nothing arrived within the read timeout; `Ok(0)` or any
/// other error means the device is gone.
pub trait Duplex: Read + Write + Send {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()>;
}

impl Duplex for serialport::TTYPort {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        serialport::SerialPort::set_timeout(self, timeout).map_err(io::Error::from)
    }
}

/// Opens (and, after the device disappeared, re-opens) a transport.
pub trait Connector: Send {
    fn open(&mut self) -> io::Result<Box<dyn Duplex>>;
    /// Human-readable name for logs and errors.
    fn describe(&self) -> String;
}

/// A serial device opened through `serialport` (8N1, no flow control).
#[derive(Debug, Clone)]
pub struct SerialConnector {
    pub path: PathBuf,
    pub baud: u32,
    /// Lock the device against other openers (TIOCEXCL + flock).
    pub exclusive: bool,
}

impl SerialConnector {
    pub fn new(path: impl Into<PathBuf>, baud: u32) -> Self {
        SerialConnector {
            path: path.into(),
            baud,
            exclusive: true,
        }
    }
}

impl Connector for SerialConnector {
    fn open(&mut self) -> io::Result<Box<dyn Duplex>> {
        // A link left by a simulated hand that died may lead elsewhere.
        crate::ptylink::check_link(&self.path)?;
        Ok(Box::new(open_serial(
            &self.path,
            self.baud,
            self.exclusive,
        )?))
    }

    fn describe(&self) -> String {
        format!("{} @ {} baud", self.path.display(), self.baud)
    }
}

/// Opens a serial device 8N1 without flow control, dropping stale input.
pub fn open_serial(
    path: &std::path::Path,
    baud: u32,
    exclusive: bool,
) -> io::Result<serialport::TTYPort> {
    let name = path.to_string_lossy().into_owned();
    let builder = serialport::new(&name, baud)
        .timeout(Duration::from_millis(10))
        .data_bits(serialport::DataBits::Eight)
        .parity(serialport::Parity::None)
        .stop_bits(serialport::StopBits::One)
        .flow_control(serialport::FlowControl::None)
        .exclusive(exclusive);
    let port = serialport::TTYPort::open(&builder)
        .map_err(|e| io::Error::new(io::ErrorKind::NotFound, format!("{name}: {e}")))?;
    // Bytes queued before we opened belong to an earlier session.
    let _ = serialport::SerialPort::clear(&port, serialport::ClearBuffer::Input);
    Ok(port)
}

/// Whether an I/O error only means "nothing arrived yet".
pub fn is_timeout(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
    )
}
