"""Footprints on the map: longitude/latitude projected to UTM, projected CRSs kept, and the
CityJSON export putting the buildings back where the footprints were."""

import json

import numpy as np
import pytest
from pyproj import Geod, Transformer

from facadeforge import derive, export, load_rules
from facadeforge.errors import InputError
from facadeforge.exchange import load
from facadeforge.geometry.footprints import load_footprints


def _square(x0, y0, d, z=None):
    ring = [[x0, y0], [x0 + d, y0], [x0 + d, y0 + d], [x0, y0 + d], [x0, y0]]
    return [p + [z] for p in ring] if z is not None else ring


def _write(tmp_path, rings, crs=None, name="fp.geojson"):
    data = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": f"b{i}"},
         "geometry": {"type": "Polygon", "coordinates": [r]}} for i, r in enumerate(rings)]}
    if crs is not None:
        data["crs"] = {"type": "name", "properties": {"name": crs}}
    p = tmp_path / name
    p.write_text(json.dumps(data))
    return p


def _extent(fp):
    return np.ptp(fp.polygon[:, 0]), np.ptp(fp.polygon[:, 2])


def test_longitude_latitude_is_projected_to_the_utm_zone(tmp_path):
    # a 0.0001-degree square in Zurich: its sides are as long as on the ellipsoid, to the
    # UTM scale factor (0.9996 on the central meridian, 9° E here)
    ring = _square(8.54, 47.37, 1e-4)
    fp = load_footprints(_write(tmp_path, [ring]))[0]
    geod = Geod(ellps="WGS84")
    sides = np.linalg.norm(np.roll(fp.polygon, -1, axis=0) - fp.polygon, axis=1)
    ellipsoid = sorted(geod.inv(*a, *b)[2] for a, b in zip(ring, ring[1:]))
    assert sorted(sides) == pytest.approx([s * 0.9996 for s in ellipsoid], rel=1e-4)
    assert fp.attributes["_crs"] == 32632
    assert "UTM zone 32N" in fp.attributes["_projected"]
    assert np.abs(fp.polygon).max() < 100  # moved near the origin, the offset recorded
    assert fp.polygon[:, 1].tolist() == [0.0] * 4


def test_southern_hemisphere_and_an_explicit_geographic_crs(tmp_path):
    fp = load_footprints(_write(tmp_path, [_square(151.2, -33.87, 2e-4)],
                                crs="urn:ogc:def:crs:OGC:1.3:CRS84"))[0]
    assert fp.attributes["_crs"] == 32756


def test_projected_crs_is_kept_and_feet_become_metres(tmp_path):
    fp = load_footprints(_write(tmp_path, [_square(500_000, 5_400_000, 10)],
                                crs="urn:ogc:def:crs:EPSG::25832"))[0]
    assert fp.attributes["_crs"] == 25832 and _extent(fp) == pytest.approx((10, 10))
    assert "_projected" not in fp.attributes
    ft = load_footprints(_write(tmp_path, [_square(980_000, 200_000, 100)], crs="EPSG:2263",
                                name="ny.geojson"))[0]  # New York Long Island, US survey feet
    assert _extent(ft) == pytest.approx((30.48006, 30.48006), rel=1e-5)
    assert ft.attributes["_crs"] == 2263


def test_small_metric_coordinates_stay_metres(tmp_path):
    fp = load_footprints(_write(tmp_path, [_square(0, 0, 20), _square(30, 0, 12)]))[0]
    assert _extent(fp) == (20.0, 20.0) and "_crs" not in fp.attributes


def test_unknown_crs_is_refused_by_name(tmp_path):
    with pytest.raises(InputError, match="unknown crs 'EPSG:999999'"):
        load_footprints(_write(tmp_path, [_square(0, 0, 20)], crs="EPSG:999999"))


def test_third_coordinate_is_the_elevation(tmp_path):
    fp = load_footprints(_write(tmp_path, [_square(0, 0, 20, z=120.0)]))[0]
    assert fp.polygon[:, 1].tolist() == [120.0] * 4


def test_cityjson_puts_the_buildings_back_on_the_map(tmp_path):
    lon, lat, d = 8.54, 47.37, 1e-4
    models = derive(load_rules("Lot --> extrude(10) X."),
                    str(_write(tmp_path, [_square(lon, lat, d)])), workers=1)
    (path, *_) = export(models, tmp_path / "b.city.json")
    doc = json.loads(path.read_text())
    assert doc["metadata"]["referenceSystem"] == "https://www.opengis.net/def/crs/EPSG/0/32632"
    assert "_crs" not in doc["CityObjects"]["b0"]["attributes"]
    pts = np.array(doc["vertices"]) * doc["transform"]["scale"] + doc["transform"]["translate"]
    to_utm = Transformer.from_crs("OGC:CRS84", "EPSG:32632", always_xy=True).transform
    corners = np.column_stack(to_utm(*np.array(_square(lon, lat, d)[:4]).T))
    ground = pts[pts[:, 2] < 0.5][:, :2]
    # every footprint corner is a ground vertex of the building, to the millimetre
    assert np.abs(ground[None] - corners[:, None]).max(axis=2).min(axis=1).max() < 2e-3
    assert pts[:, 2].max() == pytest.approx(10)


def test_cityjson_of_feet_footprints_is_in_feet(tmp_path):
    """A file in US survey feet (EPSG:2263) derives in metres, and its CityJSON, which names
    EPSG:2263, has coordinates in feet again: the footprint corners where the file had them,
    a 10 m tall building 32.8 ft tall."""
    models = derive(load_rules("Lot --> extrude(10) X."),
                    str(_write(tmp_path, [_square(980_000, 200_000, 100)], crs="EPSG:2263")),
                    workers=1)
    (path, *_) = export(models, tmp_path / "ny.city.json")
    doc = json.loads(path.read_text())
    assert doc["metadata"]["referenceSystem"].endswith("/EPSG/0/2263")
    pts = np.array(doc["vertices"]) * doc["transform"]["scale"] + doc["transform"]["translate"]
    corners = np.array(_square(980_000, 200_000, 100)[:4], float)
    ground = pts[pts[:, 2] < 0.5][:, :2]
    assert np.abs(ground[None] - corners[:, None]).max(axis=2).min(axis=1).max() < 1e-2
    assert pts[:, 2].max() == pytest.approx(10 / 0.3048006, rel=1e-5)
    extent = doc["metadata"]["geographicalExtent"]
    assert extent[0] == pytest.approx(980_000, abs=1e-2) and extent[4] == pytest.approx(200_100, abs=1e-2)


@pytest.mark.parametrize("suffix", [".glb", ".obj"])
def test_glb_and_obj_keep_the_georeference_apart_from_the_data(tmp_path, suffix):
    """Formats without a reference system hold the georeference in an entry of its own (not
    among the building's attributes), and the reloaded model writes the same CityJSON."""
    models = derive(load_rules("Lot --> extrude(10) X."),
                    str(_write(tmp_path, [_square(980_000, 200_000, 100)], crs="EPSG:2263")),
                    workers=1)
    (path, *_) = export(models, tmp_path / ("b" + suffix))
    if suffix == ".glb":
        from pygltflib import GLTF2

        extras = GLTF2().load(str(path)).nodes[0].extras
        assert not any(k.startswith("_") for k in extras["attributes"])
        assert extras["georeference"]["crs"] == 2263
        assert extras["georeference"]["unit"] == pytest.approx(0.3048006)
    else:
        text = path.read_text()
        assert '"_crs"' not in text and "# facadeforge georeference {" in text
    (again,) = load(path)
    assert again.attributes["_crs"] == 2263
    first = json.loads(export(models, tmp_path / "a.city.json")[0].read_text())
    second = json.loads(export([again], tmp_path / "b.city.json")[0].read_text())
    assert second["metadata"]["referenceSystem"] == first["metadata"]["referenceSystem"]
    assert second["transform"]["translate"] == pytest.approx(first["transform"]["translate"])
    assert second["metadata"]["geographicalExtent"] == pytest.approx(
        first["metadata"]["geographicalExtent"], abs=1e-3)
