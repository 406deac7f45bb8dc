"""Build kinmo's foreign-asset set (issue 36): articulated MuJoCo models from public
robot-learning repositories, none from PartNet-Mobility, one self-contained folder each.

The sources, their commits and licences are in ``bench/foreign/sources.json``; nothing of
them is committed to kinmo. For each source this script clones the repository at its commit
(``git clone`` + ``git checkout``; ``--git-base`` reads local mirrors instead), finds its
object models (``kind``: how that repository lays them out), and writes each object with at
least one hinge or slide joint as::

    OUT/<source>-<object>/model.xml        one MJCF file, includes inlined (mujoco.MjSpec),
                                           the object alone (no robot, floor or lights)
    OUT/<source>-<object>/assets/...       its meshes and textures, copied
    OUT/sources.json                       per object: source, repository, commit, licence,
                                           the source files, the joints (name, type)
    OUT/LICENSES/<source>                  each repository's licence text

The folder is what ``bench/bench_foreign.py`` evaluates (the true joints are the MJCF's;
kinmo's MJCF reader ignores them when predicting). It needs ``git`` and network access
(or ``--git-base``) and ``mujoco`` >= 3.2 (``MjSpec``).

``--sources bench/foreign/heldout.json`` builds the held-out set instead: sources measured
once and never used to make or tune a rule (``docs/results/foreign_assets.md``, *A held-out
source*).

Usage::

    python bench/foreign_assets.py --out foreign/ [--cache ~/.cache/kinmo/foreign]
        [--git-base 'https://github.com/{repo}.git'] [--sources bench/foreign/heldout.json]
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import mujoco
from PIL import Image  # Pillow, installed with matplotlib

from kinmo.assets.mjcf import allow_massless

REPO = Path(__file__).resolve().parent.parent
SOURCES = REPO / "bench" / "foreign" / "sources.json"
_MOVING = {int(mujoco.mjtJoint.mjJNT_HINGE): "hinge", int(mujoco.mjtJoint.mjJNT_SLIDE): "slide"}


def checkout(repo: str, commit: str, root: str, cache: Path, git_base: str) -> tuple[Path, list[str]]:
    """The files under ``root`` of ``repo`` at ``commit``, written under ``cache``.

    The repository is cloned once (``git clone --no-checkout``), then each file under ``root``
    is written from its blob. A blob the clone lacks (a partial mirror) is skipped and
    listed; a missing texture is then replaced by a grey one (:func:`write_object`).
    """
    git = cache / "git" / repo.replace("/", "+")
    if not (git / "HEAD").is_file():
        if git.exists():
            shutil.rmtree(git)
        url = git_base.format(repo=repo, owner=repo.split("/")[0], name=repo.split("/")[1])
        subprocess.run(["git", "clone", "-q", "--bare", url, str(git)], check=True)
    dest = cache / "files" / repo.replace("/", "+") / commit
    missing: list[str] = []
    if not (dest / ".complete").is_file():
        if dest.exists():
            shutil.rmtree(dest)
        listing = subprocess.run(["git", "-C", str(git), "ls-tree", "-r", "-z", commit, "--", root or "."],
                                 check=True, capture_output=True).stdout.decode()
        for entry in filter(None, listing.split("\0")):
            meta, path = entry.split("\t", 1)
            mode, kind, sha = meta.split()
            if kind != "blob" or mode == "120000":
                continue
            blob = subprocess.run(["git", "-C", str(git), "cat-file", "blob", sha], capture_output=True)
            if blob.returncode != 0:
                missing.append(path)
                continue
            (dest / path).parent.mkdir(parents=True, exist_ok=True)
            (dest / path).write_bytes(blob.stdout)
        (dest / ".complete").write_text("\n".join(missing))
    else:
        missing = [m for m in (dest / ".complete").read_text().split("\n") if m]
    return dest, missing


def metaworld_objects(root: Path, exclude: set[str]) -> list[tuple[str, str, list[str]]]:
    """Meta-World's objects: ``objects/assets/NAME.xml`` with its ``*_dependencies.xml``.

    Returns (object name, wrapper XML text, source files); the wrapper lives in ``root/_kinmo``
    so that the repository's ``../objects/...`` paths resolve.
    """
    assets = root / "objects" / "assets"
    out = []
    for f in sorted(assets.glob("*.xml")):
        name = f.stem
        if name.endswith("_dependencies") or name in exclude:
            continue
        deps = None
        for k in range(len(name), 2, -1):  # doorlockA -> doorlock_dependencies.xml
            cand = assets / f"{name[:k]}_dependencies.xml"
            if cand.is_file():
                deps = cand
                break
        head = f'<include file="../objects/assets/{deps.name}"/>' if deps else ""
        xml = (f'<mujoco model="{name}">{head}<worldbody><body>'
               f'<include file="../objects/assets/{f.name}"/></body></worldbody></mujoco>')
        out.append((name, xml, [str(p.relative_to(root.parent.parent)) for p in (f, deps) if p]))
    return out


def furniture_sim_objects(root: Path, exclude: set[str], together: set[str]) -> list[tuple[str, str, list[str]]]:
    """furniture_sim's objects: ``DIR/*_body*.xml`` with ``DIR/*_asset*.xml``, as its top-level
    ``DIR.xml`` composes them: one object per body file, or one per ``DIR`` in ``together``
    (bodies tied by equality constraints: lights and their buttons). The wrapper sits in the
    repository root, named ``furniture_sim`` so that its ``../furniture_sim/...`` paths
    resolve."""
    out = []
    for d in sorted(p for p in root.iterdir() if p.is_dir()):
        assets = sorted(d.glob("*_asset*.xml"))
        bodies = sorted(d.glob("*_body*.xml"))
        groups = [(d.name, bodies)] if d.name in together else [(b.stem.replace("_body", ""), [b]) for b in bodies]
        for name, group in groups:
            if name in exclude or not assets:
                continue
            inc = "".join(f'<include file="../furniture_sim/{d.name}/{a.name}"/>' for a in assets)
            body = "".join(f'<include file="../furniture_sim/{d.name}/{b.name}"/>' for b in group)
            xml = (f'<mujoco model="{name}"><compiler angle="radian" meshdir="" texturedir=""/>{inc}'
                   f'<worldbody><body>{body}</body></worldbody></mujoco>')
            out.append((name, xml, [str(p.relative_to(root)) for p in (*assets, *group)]))
    return out


def mjcf_file_objects(root: Path, exclude: set[str]) -> list[tuple[str, str, list[str]]]:
    """Stand-alone MJCF object files (``kind`` ``mjcf_files``: LIBERO's
    ``assets/articulated_objects/NAME.xml``): each ``root/*.xml`` is one object, its text the
    wrapper, written beside it so that its relative paths resolve as in the repository."""
    return [(f.stem, f.read_text(), [str(f.relative_to(root.parent))])
            for f in sorted(root.glob("*.xml")) if f.stem not in exclude]


def urdf_objects(repo_dir: Path, src: dict, out: Path, keep_dae: bool = False) -> list[dict]:
    """Objects cut from one URDF scene (``kind`` ``urdf_split``): every child link of a link
    in ``split`` (without ``split``: the URDF's root link, the whole URDF one object) with a
    moving joint below it becomes ``OUT/<source>-<link>/model.urdf``: the
    subtree with its joints (types kept: the truth), under a root ``base`` fixed at the
    subtree's pose in the scene (so up stays up), the meshes it names copied beside it under
    a ``package.xml`` of the same package name (``package://`` then resolves inside the
    folder). Visual meshes kinmo cannot read without extra packages (``.dae``: pycollada)
    are dropped where the link has a collision element (the same parts, simplified), unless
    ``keep_dae``."""
    import xml.etree.ElementTree as ET

    from scipy.spatial.transform import Rotation

    from kinmo.assets.urdf import link_poses

    urdf = repo_dir / src["urdf"]
    package_dir = repo_dir / src["package_dir"]
    robot = ET.parse(urdf).getroot()
    links = {lk.get("name"): lk for lk in robot.findall("link")}
    children: dict[str, list[ET.Element]] = {}
    for j in robot.findall("joint"):
        children.setdefault(j.find("parent").get("link"), []).append(j)
    poses = link_poses(robot, urdf)
    moving = {"revolute", "continuous", "prismatic"}

    def below(link: str) -> list[ET.Element]:
        return [j for j in children.get(link, []) for j in (j, *below(j.find("child").get("link")))]

    if src.get("split"):
        roots = [j0.find("child").get("link") for top in src["split"] for j0 in children.get(top, [])]
    else:  # the whole URDF is one object: its root link
        child_links = {j.find("child").get("link") for j in robot.findall("joint")}
        roots = [name for name in links if name not in child_links][:1]
    rows = []
    for root in roots:
        joints = below(root)
        if not any(j.get("type") in moving for j in joints):
            continue
        oid = f"{src['name']}-{root}"
        folder = out / oid
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        shutil.copyfile(package_dir / "package.xml", folder / "package.xml")
        T = poses[root]
        xyz = " ".join(f"{x:.9g}" for x in T[:3, 3])
        rpy = " ".join(f"{x:.9g}" for x in Rotation.from_matrix(T[:3, :3]).as_euler("xyz"))
        new = ET.Element("robot", name=root)
        ET.SubElement(new, "link", name="base")
        fixed = ET.SubElement(new, "joint", name="base_fixed", type="fixed")
        ET.SubElement(fixed, "parent", link="base")
        ET.SubElement(fixed, "child", link=root)
        ET.SubElement(fixed, "origin", xyz=xyz, rpy=rpy)
        names = [root] + [j.find("child").get("link") for j in joints]
        missing: list[str] = []
        for name in names:
            lk = ET.fromstring(ET.tostring(links[name]))
            if lk.find("collision") is not None and not keep_dae:
                for v in lk.findall("visual"):
                    m = v.find("geometry/mesh")
                    if m is not None and m.get("filename", "").lower().endswith(".dae"):
                        lk.remove(v)
            for m in lk.iter("mesh"):
                fn = m.get("filename", "")
                prefix = f"package://{src['package']}/"
                if not fn.startswith(prefix):
                    raise SystemExit(f"{urdf}: link {name}: mesh {fn} is not in package {src['package']}")
                rel = fn[len(prefix):]
                if not (package_dir / rel).is_file():  # a partial clone lacks it
                    missing.append(rel)
                    continue
                (folder / rel).parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(package_dir / rel, folder / rel)
            new.append(lk)
        if missing:
            print(f"{oid}: skipped, {len(missing)} mesh files missing from the clone ({missing[0]})")
            shutil.rmtree(folder)
            continue
        for j in joints:
            new.append(ET.fromstring(ET.tostring(j)))
        ET.indent(new)
        (folder / "model.urdf").write_text(ET.tostring(new, encoding="unicode") + "\n")
        found = [{"name": j.get("name"), "type": j.get("type")} for j in joints if j.get("type") in moving]
        rows.append({"id": oid, "files": [src["urdf"]], "joints": found})
    return rows


def write_object(wrapper: Path, xml: str, out: Path, massless: bool = False) -> list[dict[str, str]]:
    """Compile ``xml`` (written at ``wrapper``), copy its files into ``out/assets`` and write
    ``out/model.xml``; return its hinge / slide joints (empty: nothing written). ``massless``:
    moving bodies may lack mass (files their framework completes, as robosuite does LIBERO's);
    they get the least mass and inertia kinmo's reader gives them
    (:func:`kinmo.assets.mjcf.allow_massless`), written into the copy."""
    wrapper.write_text(xml)
    try:
        spec = mujoco.MjSpec.from_file(str(wrapper))
        if massless:
            allow_massless(spec)
        for t in spec.textures:  # a texture the clone lacks: grey (geometry is what counts)
            f = wrapper.parent / spec.texturedir / t.file
            if t.file and not f.is_file():
                f.parent.mkdir(parents=True, exist_ok=True)
                Image.new("RGB", (8, 8), (128, 128, 128)).save(f, format="PNG")
        model = spec.compile()
    except ValueError as e:  # not a model on its own (a fragment of a scene), or not valid MJCF
        print(f"{out.name}: skipped, {' '.join(str(e).split())[:120]}")
        return []
    finally:
        wrapper.unlink()
    joints = [{"name": mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint_{j}",
               "type": _MOVING[int(model.jnt_type[j])]}
              for j in range(model.njnt) if int(model.jnt_type[j]) in _MOVING]
    if not joints:
        return []
    if out.exists():
        shutil.rmtree(out)
    (out / "assets").mkdir(parents=True)
    base = wrapper.parent
    for kind, items, folder in (("mesh", spec.meshes, spec.meshdir), ("texture", spec.textures, spec.texturedir)):
        for k, item in enumerate(items):
            if not item.file:
                continue
            src = (base / folder / item.file).resolve()
            dst = f"assets/{kind}{k}_{re.sub(r'[^A-Za-z0-9_.-]', '_', src.name)}"
            shutil.copyfile(src, out / dst)
            item.file = dst
    spec.meshdir = ""
    spec.texturedir = ""
    spec.modelfiledir = str(out)  # to_xml compiles: the copies are found from there
    (out / "model.xml").write_text(spec.to_xml())
    mujoco.MjModel.from_xml_path(str(out / "model.xml"))  # the copy compiles on its own
    return joints


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--cache", type=Path, default=Path.home() / ".cache" / "kinmo" / "foreign")
    ap.add_argument("--git-base", default="https://github.com/{repo}.git",
                    help="Clone URL or path template ({repo}, {owner}, {name}).")
    ap.add_argument("--keep-dae", action="store_true",
                    help="Keep URDF visual meshes in COLLADA (.dae; reading them needs pycollada) "
                         "instead of the links' collision meshes.")
    ap.add_argument("--sources", type=Path, default=None,
                    help="The manifest of sources (default bench/foreign/sources.json; "
                         "bench/foreign/heldout.json: the held-out set).")
    args = ap.parse_args(argv)
    sources = SOURCES if args.sources is None else args.sources
    manifest = json.loads(sources.read_text())
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "LICENSES").mkdir(exist_ok=True)
    rows = []
    for src in manifest["sources"]:
        repo_dir, missing = checkout(src["repo"], src["commit"], src["root"], args.cache, args.git_base)
        lic = checkout(src["repo"], src["commit"], src["license_file"], args.cache / "licenses", args.git_base)[0]
        shutil.copyfile(lic / src["license_file"], args.out / "LICENSES" / src["name"])
        if missing:
            print(f"{src['repo']}: {len(missing)} files missing from the clone (textures are replaced by grey)")
        if src["kind"] == "urdf_split":
            for row in urdf_objects(repo_dir, src, args.out, args.keep_dae):
                rows.append({"id": row["id"], "source": src["name"], "repo": src["repo"], "commit": src["commit"],
                             "license": src["license"], "files": row["files"], "joints": row["joints"]})
                print(f"{row['id']}: {len(row['joints'])} joints ({', '.join(j['type'] for j in row['joints'])})")
            continue
        if src["kind"] == "metaworld":
            root = repo_dir / src["root"]
            objects = metaworld_objects(root, set(src["exclude"]))
            where = root / "_kinmo"
        elif src["kind"] == "furniture_sim":
            # its files name "../furniture_sim/...": a link of that name beside the checkout
            link = repo_dir.parent / "furniture_sim"
            if not link.exists():
                link.symlink_to(repo_dir.name, target_is_directory=True)
            root = link
            objects = furniture_sim_objects(root, set(src["exclude"]), set(src.get("together", [])))
            where = root
        elif src["kind"] == "mjcf_files":
            root = repo_dir / src["root"]
            objects = mjcf_file_objects(root, set(src["exclude"]))
            where = root
        else:
            raise SystemExit(f"{sources}: unknown kind {src['kind']!r}")
        where.mkdir(exist_ok=True)
        for name, xml, files in objects:
            oid = f"{src['name']}-{name}"
            joints = write_object(where / f"_kinmo_{name}.xml", xml, args.out / oid,
                                  massless=src["kind"] == "mjcf_files")
            if joints:
                rows.append({"id": oid, "source": src["name"], "repo": src["repo"], "commit": src["commit"],
                             "license": src["license"], "files": files, "joints": joints})
                print(f"{oid}: {len(joints)} joints ({', '.join(j['type'] for j in joints)})")
    (args.out / "sources.json").write_text(json.dumps({"objects": rows}, indent=2) + "\n")
    n = sum(len(r["joints"]) for r in rows)
    print(f"wrote {len(rows)} objects, {n} hinge / slide joints, into {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
