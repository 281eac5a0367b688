//! Makes Rust binaries and tests of this crate that link libpython find the interpreter's own
//! libpython at run time (this machine has two Python 3.11s; without the rpath the loader picks
//! the system one). A no-op for the extension module, which does not link libpython.

fn main() {
    pyo3_build_config::add_libpython_rpath_link_args();
}
