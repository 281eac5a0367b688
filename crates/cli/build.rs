//! With the `ae` feature the binary embeds Python: make it find the interpreter's own libpython
//! at run time (this machine has two Python 3.11s; without the rpath the loader picks the system
//! one). Without the feature there is nothing to do: the default build does not link libpython.

fn main() {
    #[cfg(feature = "ae")]
    pyo3_build_config::add_libpython_rpath_link_args();
}
