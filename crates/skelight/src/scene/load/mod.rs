//! Scene file readers. Every error names the file (and line, where there is one) and says
//! what is wrong; no input makes the loader panic.

pub mod gltf;
pub mod mitsuba;
pub mod native;
pub mod obj;
pub mod ply;
pub mod serialized;

use std::path::{Component, Path, PathBuf};

use super::{Scene, SceneDescription, SceneError};

#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    At { path: PathBuf, line: Option<usize>, message: String },
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{}: {source}", path.display())]
    Scene { path: PathBuf, source: SceneError },
}

impl LoadError {
    /// Error at a line of a file (0 = no particular line).
    pub fn at(path: &Path, line: usize, message: impl Into<String>) -> LoadError {
        LoadError::At { path: path.to_path_buf(), line: (line > 0).then_some(line), message: message.into() }
    }
    pub fn io(path: &Path, source: std::io::Error) -> LoadError {
        LoadError::Io { path: path.to_path_buf(), source }
    }
}

pub(crate) fn read_text(path: &Path) -> Result<String, LoadError> {
    let bytes = std::fs::read(path).map_err(|e| LoadError::io(path, e))?;
    String::from_utf8(bytes).map_err(|e| LoadError::at(path, 0, format!("not UTF-8 text: {e}")))
}

/// Joins a relative file name to `base`, refusing absolute paths and `..` that climb out.
pub(crate) fn confined_path(base: &Path, name: &str) -> Result<PathBuf, String> {
    let rel = Path::new(name);
    if rel.is_absolute() || rel.components().any(|c| matches!(c, Component::Prefix(_) | Component::RootDir)) {
        return Err(format!("'{name}' is an absolute path; scene files may only refer to files inside their folder"));
    }
    let mut depth = 0i32;
    for c in rel.components() {
        match c {
            Component::ParentDir => depth -= 1,
            Component::Normal(_) => depth += 1,
            _ => {}
        }
        if depth < 0 {
            return Err(format!("'{name}' leaves the scene folder"));
        }
    }
    Ok(base.join(rel))
}

/// The file `name` (relative to `base`) that a scene file names, confined to the folder
/// `root`: missing files are reported missing, the path is resolved (links followed) before
/// the confinement check, and only a regular file is accepted (a FIFO would block the load
/// forever, a device such as /dev/zero would be read until memory runs out).
pub(crate) fn confined_file(root: &Path, base: &Path, name: &str) -> Result<PathBuf, String> {
    let p = confined_path(base, name)?;
    let resolved = match p.canonicalize() {
        Ok(c) => c,
        Err(_) if std::fs::symlink_metadata(&p).is_ok() => {
            return Err(format!("'{name}' is a link to a file that does not exist"))
        }
        Err(_) => return Err(format!("file '{}' not found", p.display())),
    };
    let root = if root.as_os_str().is_empty() { Path::new(".") } else { root };
    let canon_root = root.canonicalize().unwrap_or_else(|_| root.to_path_buf());
    if !resolved.starts_with(&canon_root) {
        return Err(format!(
            "'{name}' leaves the scene folder {} (it resolves to {})",
            root.display(),
            resolved.display()
        ));
    }
    if !std::fs::metadata(&resolved).is_ok_and(|m| m.is_file()) {
        return Err(format!("'{name}' is not a regular file (a folder, a FIFO or a device)"));
    }
    Ok(p)
}

/// Loads a scene description by file extension (`-D name=value` pairs go to Mitsuba files).
pub fn load_description(path: &Path, defines: &[(String, String)]) -> Result<SceneDescription, LoadError> {
    if !path.exists() {
        return Err(LoadError::at(path, 0, "file not found"));
    }
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return Err(LoadError::at(path, 0, "not a regular file (a folder, a FIFO or a device): a scene is a file"));
    }
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let root = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new(".")).to_path_buf();
    match ext.as_str() {
        "xml" => mitsuba::Loader::new(&root, defines).load(path),
        "toml" => native::load_native(path),
        "obj" | "ply" => native::load_mesh_file(path),
        "gltf" | "glb" => self::gltf::load_gltf(path),
        other => Err(LoadError::at(
            path,
            0,
            format!("unsupported scene format '.{other}' (expected .xml, .toml, .gltf, .glb, .obj or .ply)"),
        )),
    }
}

/// Loads and builds a scene ready to render.
pub fn load(path: &Path, defines: &[(String, String)]) -> Result<Scene, LoadError> {
    let mut desc = load_description(path, defines)?;
    if desc.camera.is_none() {
        desc.camera = Some(super::default_camera(&desc));
    }
    Scene::build(desc).map_err(|source| LoadError::Scene { path: path.to_path_buf(), source })
}
