//! `grasp-gen objects ...`: list, check, show and import-ycb.

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use generator::catalog::{self, compare_grasp_types, validate, ycb, Catalog};
use std::path::{Path, PathBuf};

#[derive(Subcommand, Debug)]
pub enum ObjectsCommand {
    /// Print the objects, parts, grasp types and pre-shapes, with totals.
    List(CatalogArg),
    /// Validate a catalog: fields, ids, meshes, and every box against its mesh.
    Check(CheckArgs),
    /// Draw an object's mesh and boxes from the top, front and side (PNG).
    Show(ShowArgs),
    /// Build a catalog variant from YCB meshes and an annotations.json.
    ImportYcb(ImportArgs),
}

#[derive(Args, Debug)]
pub struct CatalogArg {
    /// Catalog folder (default: $GRASP_OBJECTS, or the repository's objects/).
    #[arg(long)]
    pub catalog: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct CheckArgs {
    #[command(flatten)]
    pub catalog: CatalogArg,
    /// A YCB folder (annotations.json and meshes/): import it into a
    /// temporary catalog, check it, and compare its grasp types per object
    /// with the built-in catalog's.
    #[arg(long, conflicts_with = "catalog")]
    pub mesh_dir: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct ShowArgs {
    /// Object id, e.g. 025_mug.
    #[arg(required_unless_present = "all")]
    pub id: Option<String>,
    /// Output PNG (for one object).
    #[arg(long, required_unless_present = "all")]
    pub png: Option<PathBuf>,
    /// Draw every object, one PNG per object into --out.
    #[arg(long, requires = "out")]
    pub all: bool,
    /// Output folder for --all.
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub catalog: CatalogArg,
}

#[derive(Args, Debug)]
pub struct ImportArgs {
    /// YCB folder holding annotations.json and meshes/.
    #[arg(long)]
    pub ycb: PathBuf,
    /// Output catalog folder (object files and the chips can's hull mesh).
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(cmd: &ObjectsCommand) -> Result<()> {
    match cmd {
        ObjectsCommand::List(a) => {
            let catalog = load_unchecked(a)?;
            print!("{}", table(&catalog));
            Ok(())
        }
        ObjectsCommand::Check(a) => check(a),
        ObjectsCommand::Show(a) => show(a),
        ObjectsCommand::ImportYcb(a) => {
            let files = ycb::import(&a.ycb, &a.out)?;
            let catalog = Catalog::load_dir(&a.out)
                .with_context(|| format!("checking the imported catalog {}", a.out.display()))?;
            println!(
                "wrote {} object files to {} ({} pairs); every box touches its mesh",
                files.len(),
                a.out.display(),
                catalog.pairs().len()
            );
            Ok(())
        }
    }
}

/// The catalog of `--catalog` (or the built-in one), its boxes unchecked.
pub fn load_unchecked(a: &CatalogArg) -> Result<Catalog> {
    let dir = a.catalog.clone().unwrap_or_else(catalog::builtin_dir);
    Ok(Catalog::load_dir_unchecked(&dir)?)
}

/// The `objects list` table.
pub fn table(catalog: &Catalog) -> String {
    let mut s = format!(
        "{:<20} {:<16} {:<12} {:<18} {:<20} {:<8} tags\n",
        "object", "name", "category", "part", "grasp type", "preshape"
    );
    for o in &catalog.objects {
        for (i, p) in o.parts.iter().enumerate() {
            let mut tags = Vec::new();
            match p.upside_down {
                catalog::UpsideDown::Never => {}
                catalog::UpsideDown::May => tags.push("may_upside_down"),
                catalog::UpsideDown::Must => tags.push("upside_down"),
            }
            match p.pronation {
                catalog::Pronation::Shortest => {}
                catalog::Pronation::Supination => tags.push("supination"),
                catalog::Pronation::None => tags.push("no_pronation"),
            }
            if p.table_border {
                tags.push("table_border");
            }
            let (id, name, cat) = if i == 0 {
                (o.id.as_str(), o.name.as_str(), o.category.as_str())
            } else {
                ("", "", "")
            };
            s += &format!(
                "{:<20} {:<16} {:<12} {:<18} {:<20} {:<8} {}\n",
                id,
                name,
                cat,
                p.name,
                p.grasp_type.name(),
                p.grasp_type.preshape().name(),
                tags.join(",")
            );
        }
    }
    s += &format!(
        "\n{} objects, {} pairs\n",
        catalog.objects.len(),
        catalog.pairs().len()
    );
    for (p, n) in catalog.pairs_per_preshape() {
        s += &format!("  {:<8} {n} pairs\n", p.name());
    }
    s
}

fn check(a: &CheckArgs) -> Result<()> {
    let (catalog, _tmp) = match &a.mesh_dir {
        Some(ycb_dir) => {
            let tmp = tempdir()?;
            ycb::import(ycb_dir, &tmp)?;
            (Catalog::load_dir_unchecked(&tmp)?, Some(TempDir(tmp)))
        }
        None => (load_unchecked(&a.catalog)?, None),
    };
    println!(
        "{} objects, {} pairs: fields, ids and meshes ok",
        catalog.objects.len(),
        catalog.pairs().len()
    );
    for o in &catalog.objects {
        let touches = validate::check_object_geometry(o)?;
        for (p, t) in o.parts.iter().zip(touches) {
            println!("  {:<20} {:<18} touches: {}", o.id, p.name, t.describe());
        }
    }
    if a.mesh_dir.is_some() {
        let builtin = Catalog::load_dir_unchecked(&catalog::builtin_dir())?;
        compare_grasp_types(&builtin, &catalog)?;
        println!("grasp types per object equal the built-in catalog's");
    }
    println!("ok");
    Ok(())
}

fn show(a: &ShowArgs) -> Result<()> {
    let catalog = load_unchecked(&a.catalog)?;
    if a.all {
        let out = a.out.as_ref().context("--all needs --out DIR")?;
        for o in &catalog.objects {
            let path = out.join(format!("{}.png", o.id));
            write_object_png(o, &path)?;
            println!("{}", path.display());
        }
        return Ok(());
    }
    let id = a.id.as_deref().context("give an object id")?;
    let object = catalog.object(id).with_context(|| {
        let ids: Vec<&str> = catalog.objects.iter().map(|o| o.id.as_str()).collect();
        format!(
            "no object '{id}' in the catalog (objects: {})",
            ids.join(", ")
        )
    })?;
    let png = a.png.as_ref().context("give --png FILE")?;
    write_object_png(object, png)?;
    println!("{}", png.display());
    Ok(())
}

/// Draws an object's mesh and boxes from the top, front and side, and
/// writes the PNG atomically.
fn write_object_png(object: &catalog::ObjectSpec, path: &Path) -> Result<()> {
    let mesh = object.mesh()?;
    let img = generator::raster::render_object(object, &mesh);
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .context("encoding the PNG")?;
    Ok(grasp_support::atomic::write_atomic(path, &bytes)?)
}

fn tempdir() -> Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("grasp-gen-ycb-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}

/// Removes its folder when dropped.
struct TempDir(PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}
