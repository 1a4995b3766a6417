//! Compiles `csrc/jpeg.c` against the system's libjpeg-turbo and links it.

fn main() {
    println!("cargo::rerun-if-changed=csrc/jpeg.c");
    if let Err(error) =
        cc::Build::new().file("csrc/jpeg.c").warnings(true).extra_warnings(true).try_compile("rover_jpeg")
    {
        panic!(
            "cannot compile csrc/jpeg.c: {error}\nIt needs libjpeg-turbo's headers and library: on Debian \
             `apt-get install libjpeg62-turbo-dev` (Ubuntu: libjpeg-turbo8-dev, Fedora: libjpeg-turbo-devel)."
        );
    }
    println!("cargo::rustc-link-lib=jpeg");
}
