//! Embeds the path of the Python shared library as an rpath, so `grasp-gen`
//! (which embeds Python to drive trimesh and Blender's `bpy`) starts without
//! LD_LIBRARY_PATH on machines where libpython lives outside the linker path
//! (pyenv, conda, a custom prefix).
fn main() {
    pyo3_build_config::use_pyo3_cfgs();
    let config = pyo3_build_config::get();
    if let Some(dir) = &config.lib_dir {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{dir}");
    }
    println!("cargo:rerun-if-env-changed=PYO3_PYTHON");
}
