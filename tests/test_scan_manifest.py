"""The manifest of a scanned cloud's result names the cloud file alone."""

import rebarlib._manifest as manifest
from rebarlib.scan import cloud_manifest


def test_a_cloud_s_manifest_reads_its_own_file_and_not_the_scans_beside_it(tmp_path, monkeypatch):
    cloud = tmp_path / "station_1.xyz"
    cloud.write_text("0 0 0\n1 0 0\n", encoding="utf-8")
    (tmp_path / "station_2.xyz").write_text("5 5 5\n", encoding="utf-8")
    design = tmp_path / "design.toml"
    design.write_text("[slab]\n", encoding="utf-8")

    def no_folder(folder):
        raise AssertionError(f"the folder {folder} was read for a cloud's manifest")

    monkeypatch.setattr(manifest, "capture_digest", no_folder)
    man = cloud_manifest(cloud, design, options={"units": "m"})
    assert man["capture_folder"] is None and man["capture_digest"] is None
    assert man["cloud_file"] == str(cloud.resolve())
    assert man["cloud_digest"] == manifest.file_digest(cloud)
    assert man["design_digest"] == manifest.file_digest(design)
    assert man["method"] == "cloud" and man["options"] == {"units": "m"}
