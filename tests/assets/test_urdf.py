"""URDF input as people write it (issue 36): primitive geometry, ``package://`` meshes found
through package.xml or --package-path, collision-only links, and errors that name the fix."""

from __future__ import annotations

import os

import numpy as np
import pytest
from typer.testing import CliRunner

from assets.builders import CABINET, bounds, box_urdf, mesh_urdf, package, write_mesh
from kinmo.assets import ReadOptions, asset_up, read_parts
from kinmo.cli import app
from kinmo.errors import KinmoDataError


def test_a_urdf_of_boxes_reads_one_part_per_link_at_its_pose(tmp_path):
    parts = read_parts(box_urdf(tmp_path / "cab.urdf"))
    assert [n for n, _, _ in parts] == list(CABINET)
    for name, v, f in parts:
        c, s = CABINET[name]
        np.testing.assert_allclose(v.min(0), np.subtract(c, np.divide(s, 2)), atol=1e-9)
        np.testing.assert_allclose(v.max(0), np.add(c, np.divide(s, 2)), atol=1e-9)
        assert f.dtype == np.int64 and len(f) == 12
    assert asset_up(tmp_path / "cab.urdf") == "z"


def test_collision_geometry_serves_a_link_without_visuals(tmp_path):
    parts = read_parts(box_urdf(tmp_path / "cab.urdf", geometry="collision"))
    assert len(parts) == 4


def test_cylinders_lie_along_local_z_turned_by_the_origin(tmp_path):
    urdf = tmp_path / "c.urdf"
    urdf.write_text(
        '<robot name="r"><link name="a"><visual><geometry><sphere radius="0.5"/></geometry></visual>'
        '</link><link name="b"><visual><origin xyz="0 0 2" rpy="0 1.5707963267948966 0"/>'
        '<geometry><cylinder radius="0.1" length="1"/></geometry></visual>'
        '<visual><origin xyz="0 0 4"/><geometry><capsule radius="0.1" length="1"/></geometry></visual>'
        '</link><joint name="j" type="fixed"><parent link="a"/><child link="b"/>'
        '<origin xyz="1 0 0"/></joint></robot>')
    (_, va, _), (_, vb, fb) = read_parts(urdf)
    np.testing.assert_allclose(np.abs(va).max(0), 0.5, atol=0.05)  # icosphere
    cyl = vb[vb[:, 2] < 3]  # pitched 90 degrees: along x, centred at (1, 0, 2)
    np.testing.assert_allclose(cyl.min(0), [0.5, -0.1, 1.9], atol=1e-6)
    np.testing.assert_allclose(cyl.max(0), [1.5, 0.1, 2.1], atol=1e-6)
    cap = vb[vb[:, 2] > 3]  # along z, the straight part 1 long plus two caps of radius 0.1
    np.testing.assert_allclose(cap[:, 2].min(), 3.4, atol=1e-6)
    np.testing.assert_allclose(cap[:, 2].max(), 4.6, atol=1e-6)


def test_mesh_scale_and_a_kinmo_urdf_in_an_xml_file(tmp_path):
    write_mesh(tmp_path / "m" / "a.obj")
    urdf = tmp_path / "r.xml"  # a URDF saved as .xml: found by its <robot> root
    urdf.write_text('<robot name="r"><link name="a"><visual><geometry><mesh filename="m/a.obj" '
                    'scale="2 1 1"/></geometry></visual></link><link name="b"><visual><geometry>'
                    '<box size="1 1 1"/></geometry></visual></link></robot>')
    parts = read_parts(urdf)
    np.testing.assert_allclose(bounds(parts[:1]), [[-1, -0.5, -0.5], [1, 0.5, 0.5]])


# ---- package:// ---------------------------------------------------------------------------

def _workspace(tmp_path):
    """src/cab/{package.xml, meshes/door.obj, urdf/cab.urdf} naming package://cab/meshes/..."""
    pkg = package(tmp_path / "ws" / "src" / "cab_pkg", "cab")
    write_mesh(pkg / "meshes" / "body.obj", offset=(0, 0, 0))
    write_mesh(pkg / "meshes" / "door.stl", offset=(2, 0, 0))
    return mesh_urdf(pkg / "urdf" / "cab.urdf", {"body": "package://cab/meshes/body.obj",
                                                 "door": "package://cab/meshes/door.stl"})


def test_package_names_resolve_through_the_nearest_package_xml(tmp_path):
    urdf = _workspace(tmp_path)
    package(tmp_path / "ws", "cab")  # a farther package of the same name is not chosen
    parts = read_parts(urdf)
    assert [n for n, _, _ in parts] == ["body", "door"]
    np.testing.assert_allclose(bounds(parts), [[-0.5, -0.5, -0.5], [2.5, 0.5, 0.5]])


def test_package_path_option_finds_a_package_without_package_xml(tmp_path):
    write_mesh(tmp_path / "pkgs" / "cab" / "meshes" / "a.obj")
    write_mesh(tmp_path / "pkgs" / "cab" / "meshes" / "b.obj", offset=(3, 0, 0))
    urdf = mesh_urdf(tmp_path / "robot" / "r.urdf", {"a": "package://cab/meshes/a.obj",
                                                     "b": "package://cab/meshes/b.obj"})
    with pytest.raises(KinmoDataError, match=r"no package.xml named 'cab' above the file; pass "
                                             r"--package-path DIR holding cab/"):
        read_parts(urdf)
    with pytest.raises(KinmoDataError, match=r"above the file nor in .*elsewhere; pass --package-path"):
        read_parts(urdf, ReadOptions((tmp_path / "elsewhere",)))
    parts = read_parts(urdf, ReadOptions((tmp_path / "elsewhere", tmp_path / "pkgs")))
    assert bounds(parts)[1, 0] == pytest.approx(3.5)


def test_predict_takes_package_path_and_refuses_it_for_a_dataset(tmp_path, tiny_gnn):
    write_mesh(tmp_path / "pkgs" / "cab" / "a.obj")
    write_mesh(tmp_path / "pkgs" / "cab" / "b.obj", offset=(0, 0, 2))
    urdf = mesh_urdf(tmp_path / "robot" / "r.urdf", {"a": "package://cab/a.obj", "b": "package://cab/b.obj"})
    args = ["predict", str(urdf), "-m", str(tiny_gnn["run"]), "--device", "cpu", "-q", "-f", "mobility_v2"]
    r = CliRunner().invoke(app, [*args, "-o", str(tmp_path / "o1")])
    assert r.exit_code == 1 and "--package-path DIR holding cab/" in " ".join(r.output.split())
    r = CliRunner().invoke(app, [*args, "-o", str(tmp_path / "o2"), "--package-path", str(tmp_path / "pkgs")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "o2" / "r" / "mobility_v2.json").is_file()
    r = CliRunner().invoke(app, ["predict", str(tmp_path / "pkgs"), "-m", str(tiny_gnn["run"]), "-o",
                                 str(tmp_path / "o3"), "--package-path", str(tmp_path), "-q"])
    assert r.exit_code == 2 and "--package-path is for your own asset" in r.output


def test_a_missing_mesh_in_a_package_names_the_package_and_the_fix(tmp_path):
    urdf = _workspace(tmp_path)
    os.remove(urdf.parents[1] / "meshes" / "door.stl")
    with pytest.raises(KinmoDataError, match=r"link 'door': mesh 'package://cab/meshes/door.stl' "
                                             r"not found in package 'cab' at .*: add the file"):
        read_parts(urdf)


def test_relative_names_may_go_up_within_the_urdfs_ros_package(tmp_path):
    """ROS packages keep meshes beside urdf/: ``../meshes/door.stl`` from pkg/urdf/ is inside
    the package, while a name leaving the package, or any ``..`` of a URDF in no package,
    is refused."""
    urdf = _workspace(tmp_path)
    mesh_urdf(urdf, {"body": "../meshes/body.obj", "door": "./../urdf/../meshes/door.stl"})
    np.testing.assert_allclose(bounds(read_parts(urdf)), [[-0.5, -0.5, -0.5], [2.5, 0.5, 0.5]])
    write_mesh(tmp_path / "ws" / "src" / "other.obj")
    mesh_urdf(urdf, {"body": "../meshes/body.obj", "evil": "../../other.obj"})
    with pytest.raises(KinmoDataError, match=r"link 'evil': mesh '../../other.obj' refused: it climbs "
                                             r"out with '..' \(mesh paths are relative inside the URDF's "
                                             r"folder, or its ROS package's"):
        read_parts(urdf)
    loose = mesh_urdf(tmp_path / "loose" / "urdf" / "r.urdf", {"a": "../meshes/a.obj"})
    write_mesh(tmp_path / "loose" / "meshes" / "a.obj")
    with pytest.raises(KinmoDataError, match="climbs out with '..'"):
        read_parts(loose)


@pytest.mark.parametrize("filename,problem", [
    ("package://../outside.obj", "package name is a relative folder reference"),
    ("package://cab/../../outside.obj", "climbs out with '..'"),
    ("package://cab/meshes/../../../outside.obj", "climbs out with '..'"),
    ("package:///etc/passwd", "package name is empty"),
    ("package://a\\b/x.obj", "package name contains a path separator"),
    ("package://cab/meshes/link.obj", "leads outside through a symbolic link"),
    ("package://cab/escape/x.obj", "leads outside through a symbolic link"),
])
def test_package_references_leaving_their_root_are_refused(tmp_path, filename, problem):
    urdf = _workspace(tmp_path)
    outside = write_mesh(tmp_path / "outside.obj")
    (urdf.parents[1] / "meshes" / "link.obj").symlink_to(outside)
    (urdf.parents[1] / "escape").symlink_to(tmp_path, target_is_directory=True)
    (tmp_path / "x.obj").write_text(outside.read_text())
    mesh_urdf(urdf, {"body": "package://cab/meshes/body.obj", "evil": filename})
    with pytest.raises(KinmoDataError) as e:
        read_parts(urdf)
    msg = str(e.value)
    assert "link 'evil'" in msg and "refused" in msg and problem in msg and "\n" not in msg


def test_a_package_root_that_is_a_link_keeps_its_files_inside_it(tmp_path):
    # the package found by --package-path may be a link; its files must stay inside its target
    real = tmp_path / "real_cab"
    write_mesh(real / "a.obj")
    write_mesh(real / "b.obj", offset=(2, 0, 0))
    (tmp_path / "pkgs").mkdir()
    (tmp_path / "pkgs" / "cab").symlink_to(real, target_is_directory=True)
    urdf = mesh_urdf(tmp_path / "r" / "r.urdf", {"a": "package://cab/a.obj", "b": "package://cab/b.obj"})
    assert len(read_parts(urdf, ReadOptions((tmp_path / "pkgs",)))) == 2


# ---- errors name the fix ------------------------------------------------------------------

@pytest.mark.parametrize("geometry,needle", [
    ('<box size="1 1"/>', r"<box size> is '1 1'; it must be 3 finite number\(s\)"),
    ('<box size="1 nan 1"/>', "<box size> is '1 nan 1'"),
    ('<box size="1 0 1"/>', r"<box> takes 3 finite positive size\(s\), not \[1.0, 0.0, 1.0\]"),
    ("<cylinder radius=\"1\"/>", "<cylinder length> is missing"),
    ('<mesh filename="a.obj" scale="x"/>', "<mesh scale> is 'x'"),
    ("<cone/>", r"unknown geometry <cone> \(kinmo reads mesh, box, cylinder, sphere or capsule\)"),
    ('<mesh filename="nothere.obj"/>', r"mesh 'nothere.obj' not found beside the URDF \(looked for"),
])
def test_bad_geometry_is_one_line_naming_the_link_and_the_fix(tmp_path, geometry, needle):
    write_mesh(tmp_path / "a.obj")
    urdf = tmp_path / "r.urdf"
    urdf.write_text(f'<robot name="r"><link name="a"><visual><geometry><box size="1 1 1"/></geometry>'
                    f'</visual></link><link name="b"><visual><geometry>{geometry}</geometry></visual>'
                    '</link></robot>')
    with pytest.raises(KinmoDataError, match=needle) as e:
        read_parts(urdf)
    assert str(e.value).startswith(str(urdf)) and "link 'b'" in str(e.value)


def test_joint_cycles_and_other_roots_are_refused(tmp_path):
    urdf = tmp_path / "r.urdf"
    urdf.write_text('<robot name="r"><link name="a"/><link name="b"/>'
                    '<joint name="1" type="fixed"><parent link="a"/><child link="b"/></joint>'
                    '<joint name="2" type="fixed"><parent link="b"/><child link="a"/></joint></robot>')
    with pytest.raises(KinmoDataError, match="the joints form a cycle through link"):
        read_parts(urdf)
    other = tmp_path / "s.urdf"
    other.write_text("<sdf/>")
    with pytest.raises(KinmoDataError, match="not a URDF: its root element is <sdf>"):
        read_parts(other)


def test_a_long_chain_of_links_is_posed_without_recursion(tmp_path):
    n = 1500  # deeper than Python's recursion limit
    links = "".join(f'<link name="l{k}"><visual><geometry><box size="1 1 1"/></geometry></visual></link>'
                    for k in range(n))
    joints = "".join(f'<joint name="j{k}" type="fixed"><parent link="l{k}"/><child link="l{k + 1}"/>'
                     '<origin xyz="0 0 1"/></joint>' for k in range(n - 1))
    (tmp_path / "c.urdf").write_text(f'<robot name="c">{links}{joints}</robot>')
    parts = read_parts(tmp_path / "c.urdf")
    assert bounds(parts)[1, 2] == pytest.approx(n - 0.5)
