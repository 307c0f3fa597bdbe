"""Types of the Landform API, generated from openapi.yaml by clients/python/generate_types.py.

Do not edit: run `python clients/python/generate_types.py` after the server's schema changes
(a test fails while this file differs from what the generator writes).
"""

# ruff: noqa
import sys
from typing import Any, Literal, Union

if sys.version_info >= (3, 11):
    from typing import NotRequired, TypedDict
else:  # pragma: no cover
    from typing_extensions import NotRequired, TypedDict

KINDS: tuple[str, ...] = ('bulldoze', 'carve-coast', 'deform-terrain', 'erode', 'grow-cave', 'weather-column')
Kind = Literal['bulldoze', 'carve-coast', 'deform-terrain', 'erode', 'grow-cave', 'weather-column']

# Every path of the document and its methods.
PATHS: dict[str, tuple[str, ...]] = {
    '/healthz': ('GET',),
    '/metrics': ('GET',),
    '/readyz': ('GET',),
    '/v1/drafts/bulldoze': ('POST',),
    '/v1/drafts/carve-coast': ('POST',),
    '/v1/drafts/deform-terrain': ('POST',),
    '/v1/drafts/erode': ('POST',),
    '/v1/drafts/grow-cave': ('POST',),
    '/v1/drafts/weather-column': ('POST',),
    '/v1/jobs': ('GET',),
    '/v1/jobs/bulldoze': ('POST',),
    '/v1/jobs/carve-coast': ('POST',),
    '/v1/jobs/deform-terrain': ('POST',),
    '/v1/jobs/erode': ('POST',),
    '/v1/jobs/grow-cave': ('POST',),
    '/v1/jobs/weather-column': ('POST',),
    '/v1/jobs/{id}': ('DELETE', 'GET'),
    '/v1/jobs/{id}/artifacts/{name}': ('GET',),
    '/v1/jobs/{id}/cancel': ('POST',),
    '/v1/jobs/{id}/events': ('GET',),
    '/v1/jobs/{id}/live.png': ('GET',),
    '/v1/jobs/{id}/replay': ('POST',),
    '/v1/jobs/{id}/sequence': ('GET',),
    '/v1/presets': ('GET',),
}

# Each operation id's method and path.
OPERATIONS: dict[str, tuple[str, str]] = {
    'cancel_job': ('POST', '/v1/jobs/{id}/cancel'),
    'delete_job': ('DELETE', '/v1/jobs/{id}'),
    'draft_bulldoze': ('POST', '/v1/drafts/bulldoze'),
    'draft_carve_coast': ('POST', '/v1/drafts/carve-coast'),
    'draft_deform_terrain': ('POST', '/v1/drafts/deform-terrain'),
    'draft_erode': ('POST', '/v1/drafts/erode'),
    'draft_grow_cave': ('POST', '/v1/drafts/grow-cave'),
    'draft_weather_column': ('POST', '/v1/drafts/weather-column'),
    'get_artifact': ('GET', '/v1/jobs/{id}/artifacts/{name}'),
    'get_job': ('GET', '/v1/jobs/{id}'),
    'get_sequence': ('GET', '/v1/jobs/{id}/sequence'),
    'healthz': ('GET', '/healthz'),
    'job_events': ('GET', '/v1/jobs/{id}/events'),
    'list_jobs': ('GET', '/v1/jobs'),
    'list_presets': ('GET', '/v1/presets'),
    'live_png': ('GET', '/v1/jobs/{id}/live.png'),
    'metrics': ('GET', '/metrics'),
    'readyz': ('GET', '/readyz'),
    'replay_job': ('POST', '/v1/jobs/{id}/replay'),
    'submit_bulldoze': ('POST', '/v1/jobs/bulldoze'),
    'submit_carve_coast': ('POST', '/v1/jobs/carve-coast'),
    'submit_deform_terrain': ('POST', '/v1/jobs/deform-terrain'),
    'submit_erode': ('POST', '/v1/jobs/erode'),
    'submit_grow_cave': ('POST', '/v1/jobs/grow-cave'),
    'submit_weather_column': ('POST', '/v1/jobs/weather-column'),
}


ArtifactMeta = TypedDict(
    'ArtifactMeta',
    {
        'name': str,
        'media_type': str,
        'bytes': int,
        'sha256': str,
        'href': str,
    },
)

AuthoredCarving = Union['AuthoredCarvingSphere', 'AuthoredCarvingCapsule']

AuthoredCarvingCapsule = TypedDict(
    'AuthoredCarvingCapsule',
    {
        'capsule': 'AuthoredCarvingCapsuleCapsule',
    },
)

AuthoredCarvingCapsuleCapsule = TypedDict(
    'AuthoredCarvingCapsuleCapsule',
    {
        'from': list[float],
        'to': list[float],
        'radius_m': float,
        'when': NotRequired['When'],
    },
)

AuthoredCarvingSphere = TypedDict(
    'AuthoredCarvingSphere',
    {
        'sphere': 'AuthoredCarvingSphereSphere',
    },
)

AuthoredCarvingSphereSphere = TypedDict(
    'AuthoredCarvingSphereSphere',
    {
        'centre': list[float],
        'radius_m': float,
        'when': NotRequired['When'],
    },
)

BoxProfile = TypedDict(
    'BoxProfile',
    {
        'width_m': NotRequired[Union[float, None]],
        'depth_m': NotRequired[Union[float, None]],
    },
)

Bubble = Union['BubbleSphere', 'BubbleEllipsoid', 'BubbleGumdrop']

BubbleEllipsoid = TypedDict(
    'BubbleEllipsoid',
    {
        'ellipsoid': 'BubbleEllipsoidEllipsoid',
    },
)

BubbleEllipsoidEllipsoid = TypedDict(
    'BubbleEllipsoidEllipsoid',
    {
        'radii': list[float],
    },
)

BubbleGumdrop = TypedDict(
    'BubbleGumdrop',
    {
        'gumdrop': 'BubbleGumdropGumdrop',
    },
)

BubbleGumdropGumdrop = TypedDict(
    'BubbleGumdropGumdrop',
    {
        'radius': NotRequired[float],
    },
)

BubbleSphere = TypedDict(
    'BubbleSphere',
    {
        'sphere': 'BubbleSphereSphere',
    },
)

BubbleSphereSphere = TypedDict(
    'BubbleSphereSphere',
    {
        'radius': NotRequired[float],
    },
)

BulldozeBerm = TypedDict(
    'BulldozeBerm',
    {
        'start': 'BulldozePoint',
        'direction_deg': NotRequired[float],
        'l': float,
        'h1': float,
        'r1': float,
        'h2': float,
        'r2': float,
        'c': NotRequired[float],
        'c2': NotRequired[float],
        'base_m': NotRequired[float],
    },
)

BulldozeBlade = TypedDict(
    'BulldozeBlade',
    {
        'width_m': float,
        'profile': NotRequired[list[tuple[float, float]]],
        'offset_m': NotRequired[float],
        'angle_deg': NotRequired[float],
    },
)

BulldozeBox = TypedDict(
    'BulldozeBox',
    {
        'center': 'BulldozePoint',
        'size_x_m': float,
        'size_z_m': float,
        'height_m': float,
        'rotation_deg': NotRequired[float],
        'base_m': NotRequired[float],
    },
)

BulldozeClamp = TypedDict(
    'BulldozeClamp',
    {
        'min_m': NotRequired[Union[float, None]],
        'max_m': NotRequired[Union[float, None]],
    },
)

BulldozeCone = TypedDict(
    'BulldozeCone',
    {
        'center': 'BulldozePoint',
        'radius_m': float,
        'height_m': float,
        'top_radius_m': NotRequired[float],
        'base_m': NotRequired[float],
    },
)

BulldozeContourPath = TypedDict(
    'BulldozeContourPath',
    {
        'height_m': float,
        'start': 'BulldozePoint',
        'length_m': float,
        'spacing_m': NotRequired[float],
        'higher_on': NotRequired['BulldozeSide'],
    },
)

BulldozeExaggerate = TypedDict(
    'BulldozeExaggerate',
    {
        'factor': float,
        'about_m': NotRequired[float],
    },
)

BulldozeGlobal = Union['BulldozeGlobalExaggerate', 'BulldozeGlobalOffsetM', 'BulldozeGlobalClamp', 'BulldozeGlobalCurve']

BulldozeGlobalClamp = TypedDict(
    'BulldozeGlobalClamp',
    {
        'clamp': 'BulldozeClamp',
    },
)

BulldozeGlobalCurve = TypedDict(
    'BulldozeGlobalCurve',
    {
        'curve': list[list[float]],
    },
)

BulldozeGlobalExaggerate = TypedDict(
    'BulldozeGlobalExaggerate',
    {
        'exaggerate': 'BulldozeExaggerate',
    },
)

BulldozeGlobalOffsetM = TypedDict(
    'BulldozeGlobalOffsetM',
    {
        'offset_m': float,
    },
)

BulldozeHalfCylinder = TypedDict(
    'BulldozeHalfCylinder',
    {
        'start': 'BulldozePoint',
        'direction_deg': NotRequired[float],
        'length_m': float,
        'radius_m': float,
        'base_m': NotRequired[float],
    },
)

BulldozeLocal = TypedDict(
    'BulldozeLocal',
    {
        'vertices': list['BulldozeLocalVertex'],
    },
)

BulldozeLocalVertex = TypedDict(
    'BulldozeLocalVertex',
    {
        'x': float,
        'z': float,
        'set_m': NotRequired[Union[float, None]],
        'offset_m': NotRequired[Union[float, None]],
    },
)

BulldozeMound = TypedDict(
    'BulldozeMound',
    {
        'center': 'BulldozePoint',
        'radius_m': float,
        'height_m': float,
        'curvature': NotRequired[float],
        'base_m': NotRequired[float],
    },
)

BulldozeOperation = Union['BulldozeOperationPrimitive', 'BulldozeOperationPass', 'BulldozeOperationLocal', 'BulldozeOperationGlobal', 'BulldozeOperationRefine']

BulldozeOperationGlobal = TypedDict(
    'BulldozeOperationGlobal',
    {
        'global': 'BulldozeGlobal',
    },
)

BulldozeOperationLocal = TypedDict(
    'BulldozeOperationLocal',
    {
        'local': 'BulldozeLocal',
    },
)

BulldozeOperationPass = TypedDict(
    'BulldozeOperationPass',
    {
        'pass': 'BulldozePass',
    },
)

BulldozeOperationPrimitive = TypedDict(
    'BulldozeOperationPrimitive',
    {
        'primitive': 'BulldozePrimitive',
    },
)

BulldozeOperationRefine = TypedDict(
    'BulldozeOperationRefine',
    {
        'refine': 'BulldozeRefine',
    },
)

BulldozeOperator = Literal['add', 'subtract', 'max', 'min', 'average', 'replace']

BulldozeParamsBody = TypedDict(
    'BulldozeParamsBody',
    {
        'terrain': 'TerrainSource',
        'window': NotRequired[Union['BulldozeWindow', None]],
        'resolution': NotRequired[Union[float, None]],
        'operations': list['BulldozeOperation'],
        'tiles': NotRequired[Union['TileGrid', None]],
        'seed': NotRequired[int],
        'label': NotRequired[str],
        'compression': NotRequired[Literal['none', 'quantize', 'meshopt']],
        'lods': NotRequired[list[float]],
    },
)

BulldozePass = TypedDict(
    'BulldozePass',
    {
        'path': NotRequired[list['BulldozePathVertex']],
        'contour': NotRequired[Union['BulldozeContourPath', None]],
        'base': NotRequired['BulldozePathBase'],
        'blade': 'BulldozeBlade',
        'operator': NotRequired['BulldozeOperator'],
        'keyframes': NotRequired[list['BulldozeProfileKeyframe']],
    },
)

BulldozePathBase = Literal['linear', 'ground']

BulldozePathVertex = TypedDict(
    'BulldozePathVertex',
    {
        'x': float,
        'z': float,
        'height': NotRequired[Union[float, None]],
    },
)

BulldozePoint = TypedDict(
    'BulldozePoint',
    {
        'x': float,
        'z': float,
    },
)

BulldozePrimitive = TypedDict(
    'BulldozePrimitive',
    {
        'shape': 'BulldozeShape',
        'operator': NotRequired['BulldozeOperator'],
    },
)

BulldozeProfileKeyframe = TypedDict(
    'BulldozeProfileKeyframe',
    {
        'vertex': int,
        'profile': list[tuple[float, float]],
    },
)

BulldozeRamp = TypedDict(
    'BulldozeRamp',
    {
        'start': 'BulldozePoint',
        'direction_deg': NotRequired[float],
        'length_m': float,
        'width_m': float,
        'end_width_m': NotRequired[Union[float, None]],
        'start_height_m': float,
        'end_height_m': float,
        'base_m': NotRequired[float],
    },
)

BulldozeRefine = TypedDict(
    'BulldozeRefine',
    {
        'resolution': float,
        'window': 'BulldozeWindow',
    },
)

BulldozeShape = Union['BulldozeShapeMound', 'BulldozeShapeBerm', 'BulldozeShapeSwale', 'BulldozeShapeTorus', 'BulldozeShapeBox', 'BulldozeShapeCone', 'BulldozeShapeHalfCylinder', 'BulldozeShapeRamp']

BulldozeShapeBerm = TypedDict(
    'BulldozeShapeBerm',
    {
        'berm': 'BulldozeBerm',
    },
)

BulldozeShapeBox = TypedDict(
    'BulldozeShapeBox',
    {
        'box': 'BulldozeBox',
    },
)

BulldozeShapeCone = TypedDict(
    'BulldozeShapeCone',
    {
        'cone': 'BulldozeCone',
    },
)

BulldozeShapeHalfCylinder = TypedDict(
    'BulldozeShapeHalfCylinder',
    {
        'half_cylinder': 'BulldozeHalfCylinder',
    },
)

BulldozeShapeMound = TypedDict(
    'BulldozeShapeMound',
    {
        'mound': 'BulldozeMound',
    },
)

BulldozeShapeRamp = TypedDict(
    'BulldozeShapeRamp',
    {
        'ramp': 'BulldozeRamp',
    },
)

BulldozeShapeSwale = TypedDict(
    'BulldozeShapeSwale',
    {
        'swale': 'BulldozeBerm',
    },
)

BulldozeShapeTorus = TypedDict(
    'BulldozeShapeTorus',
    {
        'torus': 'BulldozeTorus',
    },
)

BulldozeSide = Literal['left', 'right']

BulldozeTorus = TypedDict(
    'BulldozeTorus',
    {
        'center': 'BulldozePoint',
        'major_radius_m': float,
        'minor_radius_m': float,
        'height_m': float,
        'base_m': NotRequired[float],
    },
)

BulldozeWindow = TypedDict(
    'BulldozeWindow',
    {
        'min_x': float,
        'min_z': float,
        'max_x': float,
        'max_z': float,
    },
)

CarveCoastParamsBody = TypedDict(
    'CarveCoastParamsBody',
    {
        'terrain': 'TerrainSource',
        'sea_level': NotRequired[Union[float, None]],
        'voxel_size_m': NotRequired[Union[float, None]],
        'erosion': NotRequired['Erosion'],
        'passes': NotRequired[int],
        'warp': NotRequired[Union['Warp', None]],
        'carve': NotRequired[list['AuthoredCarving']],
        'remove_fragments': NotRequired[bool],
        'seed': NotRequired[int],
        'label': NotRequired[str],
        'compression': NotRequired[Literal['none', 'quantize', 'meshopt']],
        'lods': NotRequired[list[float]],
    },
)

Chamber = TypedDict(
    'Chamber',
    {
        'width_m': NotRequired[float],
        'depth_m': NotRequired[float],
        'height_m': NotRequired[float],
        'roof': NotRequired['Surface'],
        'floor': NotRequired['Surface'],
        'walls': NotRequired['Surface'],
        'opening': NotRequired[Union['Opening', None]],
        'samples': NotRequired[int],
    },
)

Co2 = Literal['low', 'normal', 'high', 'random']

Column = TypedDict(
    'Column',
    {
        'profile': 'Profile',
        'height_m': NotRequired[Union[float, None]],
        'floating': NotRequired[bool],
    },
)

Conditions = TypedDict(
    'Conditions',
    {
        'pluviometric_index': str,
        'drip_interval': 'DripInterval',
        'co2': 'Co2',
    },
)

Cost = TypedDict(
    'Cost',
    {
        'memory_bytes': int,
        'memory_field': str,
        'work': int,
        'work_unit': str,
        'work_field': str,
        'min_seconds': float,
        'lod_triangles': NotRequired[int],
        'lod_bytes': NotRequired[int],
    },
)

CylinderProfile = TypedDict(
    'CylinderProfile',
    {
        'radius_m': NotRequired[Union[float, None]],
    },
)

DeformConstraint = Union['DeformConstraintMatchHeightmap', 'DeformConstraintShapeMask', 'DeformConstraintRoad', 'DeformConstraintEdgeMatch', 'DeformConstraintTileable', 'DeformConstraintPoints', 'DeformConstraintPreserve', 'DeformConstraintTerraces']

DeformConstraintEdgeMatch = TypedDict(
    'DeformConstraintEdgeMatch',
    {
        'edge_match': 'DeformEdgeMatch',
    },
)

DeformConstraintMatchHeightmap = TypedDict(
    'DeformConstraintMatchHeightmap',
    {
        'match_heightmap': 'DeformMatchHeightmap',
    },
)

DeformConstraintPoints = TypedDict(
    'DeformConstraintPoints',
    {
        'points': 'DeformPoints',
    },
)

DeformConstraintPreserve = TypedDict(
    'DeformConstraintPreserve',
    {
        'preserve': 'DeformPreserve',
    },
)

DeformConstraintRoad = TypedDict(
    'DeformConstraintRoad',
    {
        'road': 'DeformRoad',
    },
)

DeformConstraintShapeMask = TypedDict(
    'DeformConstraintShapeMask',
    {
        'shape_mask': 'DeformShapeMask',
    },
)

DeformConstraintTerraces = TypedDict(
    'DeformConstraintTerraces',
    {
        'terraces': 'DeformTerraces',
    },
)

DeformConstraintTileable = TypedDict(
    'DeformConstraintTileable',
    {
        'tileable': 'DeformTileable',
    },
)

DeformEarthworks = TypedDict(
    'DeformEarthworks',
    {
        'cut_slope': NotRequired['DeformSlope'],
        'fill_slope': NotRequired['DeformSlope'],
    },
)

DeformEdge = Literal['west', 'east', 'north', 'south']

DeformEdgeMatch = TypedDict(
    'DeformEdgeMatch',
    {
        'terrain': 'TerrainSource',
        'edges': list['DeformEdge'],
        'band_cells': NotRequired[int],
        'weight': NotRequired[float],
        'seam_filter': NotRequired[bool],
    },
)

DeformHeightPoint = TypedDict(
    'DeformHeightPoint',
    {
        'x': float,
        'z': float,
        'height': float,
    },
)

DeformMaskShape = Union['DeformMaskShapeImage', 'DeformMaskShapePolygonsM']

DeformMaskShapeImage = TypedDict(
    'DeformMaskShapeImage',
    {
        'image': 'TerrainSource',
    },
)

DeformMaskShapePolygonsM = TypedDict(
    'DeformMaskShapePolygonsM',
    {
        'polygons_m': list[list['DeformPoint']],
    },
)

DeformMatchHeightmap = TypedDict(
    'DeformMatchHeightmap',
    {
        'target': 'TerrainSource',
        'weight': NotRequired[float],
    },
)

DeformPoint = TypedDict(
    'DeformPoint',
    {
        'x': float,
        'z': float,
    },
)

DeformPoints = TypedDict(
    'DeformPoints',
    {
        'points': list['DeformHeightPoint'],
        'weight': NotRequired[float],
    },
)

DeformPreserve = TypedDict(
    'DeformPreserve',
    {
        'weight': NotRequired[float],
    },
)

DeformRoad = TypedDict(
    'DeformRoad',
    {
        'path': list['DeformPoint'],
        'width_m': float,
        'height': 'DeformRoadHeight',
        'shoulder_m': NotRequired[Union[float, None]],
        'preserve_weight': NotRequired[float],
        'preserve': NotRequired[Union['DeformRoadPreserve', None]],
        'weight': NotRequired[float],
    },
)

DeformRoadHeight = Union['DeformRoadHeightConstant', 'DeformRoadHeightProfile']

DeformRoadHeightConstant = TypedDict(
    'DeformRoadHeightConstant',
    {
        'constant': float,
    },
)

DeformRoadHeightProfile = TypedDict(
    'DeformRoadHeightProfile',
    {
        'profile': 'DeformRoadProfile',
    },
)

DeformRoadPreserve = Literal['everywhere', 'corridor']

DeformRoadProfile = TypedDict(
    'DeformRoadProfile',
    {
        'max_gradient_percent': float,
    },
)

DeformShapeMask = TypedDict(
    'DeformShapeMask',
    {
        'mask': 'DeformMaskShape',
        'water_level': NotRequired[Union[float, None]],
        'margin': NotRequired[Union[float, None]],
        'weight': NotRequired[float],
    },
)

DeformSlope = TypedDict(
    'DeformSlope',
    {
        'h_per_v': NotRequired[Union[float, None]],
        'degrees': NotRequired[Union[float, None]],
    },
)

DeformTerraceRegion = TypedDict(
    'DeformTerraceRegion',
    {
        'polygon_m': list['DeformPoint'],
        'level_m': float,
    },
)

DeformTerraces = TypedDict(
    'DeformTerraces',
    {
        'regions': list['DeformTerraceRegion'],
        'weight': NotRequired[float],
    },
)

DeformTerrainParamsBody = TypedDict(
    'DeformTerrainParamsBody',
    {
        'terrain': 'TerrainSource',
        'constraints': list['DeformConstraint'],
        'max_iterations': NotRequired[int],
        'epsilon': NotRequired[float],
        'stall_iterations': NotRequired[int],
        'stall_gain': NotRequired[float],
        'p': NotRequired[float],
        'top_fraction': NotRequired[float],
        'amplitudes': NotRequired[int],
        'radii': NotRequired[int],
        'min_radius_cells': NotRequired[int],
        'max_radius_cells': NotRequired[Union[int, None]],
        'max_displacement_ratio': NotRequired[float],
        'coarse_spacing_cells': NotRequired[Union[int, None]],
        'min_spacing_cells': NotRequired[int],
        'prediction': NotRequired[bool],
        'prediction_constant': NotRequired[float],
        'batch': NotRequired[int],
        'tiles': NotRequired[Union['TileGrid', None]],
        'sequence_tolerance_m': NotRequired[Union[float, None]],
        'keep_weight': NotRequired[float],
        'max_free_change': NotRequired[float],
        'max_slope_ratio': NotRequired[float],
        'slope_percentile': NotRequired[float],
        'earthworks': NotRequired['DeformEarthworks'],
        'seed': NotRequired[int],
        'label': NotRequired[str],
        'compression': NotRequired[Literal['none', 'quantize', 'meshopt']],
        'lods': NotRequired[list[float]],
    },
)

DeformTileAxes = Literal['both', 'x', 'z']

DeformTileable = TypedDict(
    'DeformTileable',
    {
        'edges': NotRequired['DeformTileAxes'],
        'band_cells': NotRequired[int],
        'weight': NotRequired[float],
    },
)

DripInterval = Literal['dry', 'standard', 'wet', 'random', 'pluviometric']

ErodeBaseLevel = Literal['all', 'sea', 'none']

ErodeChannel = Literal['r', 'g', 'b', 'a']

ErodeHydraulic = TypedDict(
    'ErodeHydraulic',
    {
        'k': NotRequired[float],
        'm': NotRequired[float],
        'n': NotRequired[float],
        'uplift_m_per_yr': NotRequired[float],
        'deposition_g': NotRequired[float],
        'flow_exponent': NotRequired[float],
        'erodibility_map': NotRequired[Union['ErodePaintedMap', None]],
        'uplift_map': NotRequired[Union['ErodePaintedMap', None]],
    },
)

ErodeKeep = Union['ErodeKeepPolygon2', 'ErodeKeepWorkedBy']

ErodeKeepPoint = TypedDict(
    'ErodeKeepPoint',
    {
        'x': float,
        'z': float,
    },
)

ErodeKeepPolygon = TypedDict(
    'ErodeKeepPolygon',
    {
        'points_m': list['ErodeKeepPoint'],
        'shoulder_m': NotRequired[float],
    },
)

ErodeKeepPolygon2 = TypedDict(
    'ErodeKeepPolygon2',
    {
        'polygon': 'ErodeKeepPolygon',
    },
)

ErodeKeepWorked = TypedDict(
    'ErodeKeepWorked',
    {
        'job': str,
        'shoulder_m': NotRequired[float],
    },
)

ErodeKeepWorkedBy = TypedDict(
    'ErodeKeepWorkedBy',
    {
        'worked_by': 'ErodeKeepWorked',
    },
)

ErodePaintedMap = TypedDict(
    'ErodePaintedMap',
    {
        'png': NotRequired[Union['ImageUpload', None]],
        'splat_of': NotRequired[Union['ErodeSplatChannel', None]],
        'black': float,
        'white': float,
    },
)

ErodeParamsBody = TypedDict(
    'ErodeParamsBody',
    {
        'terrain': 'TerrainSource',
        'sea_level': NotRequired[float],
        'iterations': NotRequired[int],
        'time_step_years': NotRequired[float],
        'hydraulic': NotRequired[Union['ErodeHydraulic', None]],
        'thermal': NotRequired[Union['ErodeThermal', None]],
        'base_level': NotRequired['ErodeBaseLevel'],
        'keep': NotRequired[list['ErodeKeep']],
        'tiles': NotRequired[Union['TileGrid', None]],
        'seed': NotRequired[int],
        'label': NotRequired[str],
        'compression': NotRequired[Literal['none', 'quantize', 'meshopt']],
        'lods': NotRequired[list[float]],
    },
)

ErodeSplatChannel = TypedDict(
    'ErodeSplatChannel',
    {
        'job': str,
        'channel': 'ErodeChannel',
    },
)

ErodeThermal = TypedDict(
    'ErodeThermal',
    {
        'talus_angle_deg': NotRequired[float],
        'diffusivity_m2_per_yr': NotRequired[float],
    },
)

Erosion = TypedDict(
    'Erosion',
    {
        'seed_min_slope': NotRequired[float],
        'seed_elevation_range': NotRequired[list[float]],
        'seed_acceptance_probability': NotRequired[float],
        'radius_range': NotRequired[list[float]],
        'growth_step_range': NotRequired[list[int]],
        'growth_sphere_range': NotRequired[list[int]],
    },
)

FieldError = TypedDict(
    'FieldError',
    {
        'field': str,
        'message': str,
    },
)

FractalParams = TypedDict(
    'FractalParams',
    {
        'size': NotRequired[int],
        'cell_size': NotRequired[float],
        'relief': NotRequired[float],
        'octaves': NotRequired[int],
        'roughness': NotRequired[float],
        'seed': NotRequired[int],
        'island': NotRequired[bool],
        'generator': NotRequired[int],
    },
)

GridSize = TypedDict(
    'GridSize',
    {
        'x': int,
        'y': int,
        'z': int,
    },
)

GrowCaveParamsBody = TypedDict(
    'GrowCaveParamsBody',
    {
        'chamber': NotRequired['Chamber'],
        'sites': 'Sites',
        'conditions': NotRequired['Conditions'],
        'mineral': NotRequired['Mineral'],
        'intensity': NotRequired[float],
        'rings': NotRequired[int],
        'segments': NotRequired[int],
        'stalactite_radius_m': NotRequired[float],
        'stalagmite_radius_m': NotRequired[float],
        'radius_step_m': NotRequired[float],
        'height_step_m': NotRequired[float],
        'kf_m': NotRequired[float],
        'coating_share': NotRequired[float],
        'canal_radius_m': NotRequired[float],
        'straw_max_radius_m': NotRequired[float],
        'wind': NotRequired[Union['Wind', None]],
        'manual': NotRequired[Union['Manual', None]],
        'seed': NotRequired[int],
        'label': NotRequired[str],
        'compression': NotRequired[Literal['none', 'quantize', 'meshopt']],
        'lods': NotRequired[list[float]],
    },
)

HeightmapUpload = TypedDict(
    'HeightmapUpload',
    {
        'png_base64': NotRequired[Union[str, None]],
        'png_sha256': NotRequired[Union[str, None]],
        'cell_size': NotRequired[float],
        'z_min': NotRequired[float],
        'z_max': NotRequired[float],
    },
)

ImageUpload = TypedDict(
    'ImageUpload',
    {
        'png_base64': NotRequired[Union[str, None]],
        'png_sha256': NotRequired[Union[str, None]],
    },
)

Job = TypedDict(
    'Job',
    {
        'id': str,
        'kind': str,
        'status': 'JobStatus',
        'label': NotRequired[Union[str, None]],
        'created_at': str,
        'started_at': NotRequired[Union[str, None]],
        'finished_at': NotRequired[Union[str, None]],
        'progress': 'Progress',
        'request': dict[str, Any],
        'request_omitted': NotRequired[bool],
        'result': NotRequired[Union[dict[str, Any], None]],
        'artifacts': list['ArtifactMeta'],
        'error': NotRequired[Union['Problem', None]],
        'replay_of': NotRequired[Union[str, None]],
        'replay_until_step': NotRequired[Union[int, None]],
        'cost': NotRequired[Union['Cost', None]],
    },
)

JobPage = TypedDict(
    'JobPage',
    {
        'items': list['Job'],
        'next_cursor': NotRequired[Union[str, None]],
    },
)

JobStatus = Literal['queued', 'running', 'succeeded', 'failed', 'cancelled']

JointSystem = TypedDict(
    'JointSystem',
    {
        'spacing_m': list[float],
        'width_m': float,
        'jitter': NotRequired[float],
        'wander_m': NotRequired[float],
        'seed': NotRequired[int],
    },
)

Layer = TypedDict(
    'Layer',
    {
        'top_m': float,
        'resistance': NotRequired[float],
        'noise': NotRequired['LayerNoise'],
        'bubble': NotRequired['Bubble'],
    },
)

LayerNoise = TypedDict(
    'LayerNoise',
    {
        'amplitude': NotRequired[float],
        'frequency_per_m': NotRequired[float],
    },
)

Manual = TypedDict(
    'Manual',
    {
        'stalactite': NotRequired[list['ManualRing']],
        'stalagmite': NotRequired[list['ManualRing']],
    },
)

ManualRing = TypedDict(
    'ManualRing',
    {
        'radius_m': float,
        'height_m': float,
    },
)

MeshOptions = TypedDict(
    'MeshOptions',
    {
        'smoothing_iterations': NotRequired[int],
    },
)

Mineral = Literal['calcareous', 'iron', 'manganese', 'copper', 'malachite', 'random']

Opening = TypedDict(
    'Opening',
    {
        'wall': 'Side',
        'centre_m': float,
        'width_m': float,
        'height_m': float,
        'length_m': NotRequired[float],
    },
)

PolygonProfile = TypedDict(
    'PolygonProfile',
    {
        'points_m': list[list[float]],
    },
)

Problem = TypedDict(
    'Problem',
    {
        'type': str,
        'title': str,
        'status': int,
        'detail': str,
        'errors': NotRequired[list['FieldError']],
        'memory_estimate_bytes': NotRequired[int],
        'memory_budget_bytes': NotRequired[int],
        'work_estimate_seconds': NotRequired[float],
        'time_limit_seconds': NotRequired[int],
    },
)

Profile = Union['ProfileBox', 'ProfileCylinder', 'ProfilePolygon', 'ProfileJointMap', 'ProfileJoints']

ProfileBox = TypedDict(
    'ProfileBox',
    {
        'box': 'BoxProfile',
    },
)

ProfileCylinder = TypedDict(
    'ProfileCylinder',
    {
        'cylinder': 'CylinderProfile',
    },
)

ProfileJointMap = TypedDict(
    'ProfileJointMap',
    {
        'joint_map': 'ImageUpload',
    },
)

ProfileJoints = TypedDict(
    'ProfileJoints',
    {
        'joints': 'JointSystem',
    },
)

ProfilePolygon = TypedDict(
    'ProfilePolygon',
    {
        'polygon': 'PolygonProfile',
    },
)

Progress = TypedDict(
    'Progress',
    {
        'fraction': float,
        'step': int,
        'steps': int,
        'stage': str,
        'message': str,
    },
)

ReplayRequest = TypedDict(
    'ReplayRequest',
    {
        'until_step': NotRequired[Union[int, None]],
    },
)

Side = Literal['west', 'east', 'north', 'south']

Site = TypedDict(
    'Site',
    {
        'x_m': float,
        'z_m': float,
        'conditions': NotRequired[Union['Conditions', None]],
        'mineral': NotRequired[Union['Mineral', None]],
    },
)

Sites = Union['SitesExplicit', 'SitesScatter']

SitesExplicit = TypedDict(
    'SitesExplicit',
    {
        'explicit': list['Site'],
    },
)

SitesScatter = TypedDict(
    'SitesScatter',
    {
        'scatter': 'SitesScatterScatter',
    },
)

SitesScatterScatter = TypedDict(
    'SitesScatterScatter',
    {
        'count': int,
        'min_spacing_m': NotRequired[float],
    },
)

SseEvent = TypedDict(
    'SseEvent',
    {
        'event': NotRequired[Union[str, None]],
        'id': NotRequired[Union[str, None]],
        'data': str,
        'retry': NotRequired[Union[int, None]],
    },
)

Surface = TypedDict(
    'Surface',
    {
        'relief_m': NotRequired[float],
        'frequency_per_m': NotRequired[float],
    },
)

TerrainSource = Union['TerrainSourceFractal', 'TerrainSourceHeightmap', 'TerrainSourceJob']

TerrainSourceFractal = TypedDict(
    'TerrainSourceFractal',
    {
        'fractal': 'FractalParams',
    },
)

TerrainSourceHeightmap = TypedDict(
    'TerrainSourceHeightmap',
    {
        'heightmap': 'HeightmapUpload',
    },
)

TerrainSourceJob = TypedDict(
    'TerrainSourceJob',
    {
        'job': str,
    },
)

TileGrid = TypedDict(
    'TileGrid',
    {
        'count': list[int],
        'skirt_m': NotRequired[float],
    },
)

Update = Literal['synchronized', 'event_based']

Warp = TypedDict(
    'Warp',
    {
        'amplitude_m': float,
        'frequency_per_m': float,
    },
)

WeatherColumnParamsBody = TypedDict(
    'WeatherColumnParamsBody',
    {
        'grid': 'GridSize',
        'voxel_size_m': NotRequired[float],
        'column': 'Column',
        'layers': list['Layer'],
        'rate': NotRequired[float],
        'ratio_exponent': NotRequired[float],
        'update': NotRequired['Update'],
        'gravity': NotRequired[bool],
        'steps': NotRequired[int],
        'stop_at_fraction': NotRequired[float],
        'mesh': NotRequired['MeshOptions'],
        'seed': NotRequired[int],
        'label': NotRequired[str],
        'compression': NotRequired[Literal['none', 'quantize', 'meshopt']],
        'lods': NotRequired[list[float]],
    },
)

When = Literal['before', 'after']

Wind = TypedDict(
    'Wind',
    {
        'direction': NotRequired[Union[list[float], None]],
        'intensity': NotRequired[Union[float, None]],
        'scale': NotRequired[float],
    },
)


# Each kind's request body.
REQUEST_BODIES: dict[str, Any] = {
    'bulldoze': BulldozeParamsBody,
    'carve-coast': CarveCoastParamsBody,
    'deform-terrain': DeformTerrainParamsBody,
    'erode': ErodeParamsBody,
    'grow-cave': GrowCaveParamsBody,
    'weather-column': WeatherColumnParamsBody,
}
