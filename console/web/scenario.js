// The scenario being edited: a SimulationRun document as JSON, its defaults, and the
// geometry helpers the plan map draws it with.

/** A new scenario: what examples/quickstart.yaml holds. */
export function defaultDocument() {
  return {
    apiVersion: 'sadesim.io/v1alpha1',
    kind: 'SimulationRun',
    metadata: { name: 'quickstart' },
    spec: {
      origin: { latitudeDeg: 41.8796, longitudeDeg: -87.6237, altitudeMslM: 181 },
      duration: '3m',
      clock: { mode: 'asFastAsPossible' },
      seed: 1,
      world: {
        openAreas: [
          { name: 'Millennium Park and Grant Park (north)', center: { latitudeDeg: 41.8818, longitudeDeg: -87.6226 }, radiusM: 250 },
        ],
      },
      fleet: [
        {
          name: 'scouts',
          count: 4,
          airframe: 'x500',
          operator: 'quickstart',
          homes: { randomInArea: { name: 'Millennium Park', center: { latitudeDeg: 41.8826, longitudeDeg: -87.6225 }, radiusM: 100 } },
          altitude: { maxAglM: 60 },
          mission: {
            speedMps: 8,
            items: [
              { takeoff: { altitudeAglM: 30 } },
              { waypoint: { latitudeDeg: 41.8827, longitudeDeg: -87.6233, altitudeAglM: 40 } },
              { waypoint: { latitudeDeg: 41.8816, longitudeDeg: -87.624, altitudeAglM: 40, holdS: 3 } },
              { waypoint: { latitudeDeg: 41.8815, longitudeDeg: -87.6212, altitudeAglM: 40 } },
              { loiter: { holdS: 10 } },
              { returnToLaunch: {} },
            ],
          },
        },
      ],
      zones: [
        {
          name: 'museum',
          polygon: [
            { latitudeDeg: 41.8801, longitudeDeg: -87.6242 },
            { latitudeDeg: 41.879, longitudeDeg: -87.6242 },
            { latitudeDeg: 41.879, longitudeDeg: -87.6228 },
            { latitudeDeg: 41.8801, longitudeDeg: -87.6228 },
          ],
          ceiling: { heightM: 60, reference: 'agl' },
          policy: { authorizedOperators: ['chicago-dps'] },
        },
      ],
      criteria: [{ noCrashes: {} }, { altitudeLimitsRespected: {} }],
    },
  };
}

export const MISSION_KINDS = ['takeoff', 'waypoint', 'loiter', 'randomWaypoints', 'returnToLaunch', 'land'];
export const CRITERION_KINDS = ['noUnauthorizedEntries', 'zoneConstraintsRespected', 'altitudeLimitsRespected', 'noCrashes', 'minSeparation', 'reachZone', 'zoneVerdicts', 'estimatedPositionError'];
export const AIRFRAMES = ['x500', 'mini250'];
export const ROLES = ['publicSafety', 'journalist', 'recreational', 'commercial', 'delivery', 'other'];

/** The kind of a one-of object (`{takeoff: {...}}` -> 'takeoff'). */
export function kindOf(item) {
  return item && typeof item === 'object' ? Object.keys(item)[0] : undefined;
}

export function newMissionItem(kind, at) {
  switch (kind) {
    case 'takeoff': return { takeoff: { altitudeAglM: 30 } };
    case 'waypoint': return { waypoint: { latitudeDeg: at ? at.latitudeDeg : 0, longitudeDeg: at ? at.longitudeDeg : 0, altitudeAglM: (at && at.altitudeAglM) || 40 } };
    case 'loiter': return { loiter: { holdS: 10 } };
    case 'randomWaypoints': return { randomWaypoints: { count: 5, minAltitudeAglM: 20, maxAltitudeAglM: 40 } };
    case 'returnToLaunch': return { returnToLaunch: {} };
    case 'land': return { land: {} };
    default: return { [kind]: {} };
  }
}

export function newCriterion(kind, doc) {
  const groups = ((doc.spec && doc.spec.fleet) || []).map((g) => g.name).filter(Boolean).slice(0, 1);
  const zone = (((doc.spec && doc.spec.zones) || [])[0] || {}).name || '';
  switch (kind) {
    case 'minSeparation': return { minSeparation: { distanceM: 5 } };
    case 'reachZone': return { reachZone: { groups, zone, within: '5m' } };
    case 'zoneVerdicts': return { zoneVerdicts: { groups, zone, expect: 'denied' } };
    case 'estimatedPositionError': return { estimatedPositionError: { maxHorizontalM: 5 } };
    default: return { [kind]: {} };
  }
}

/** Positions are kept to 7 decimals (about 1 cm). */
export function pos(lngLat) {
  const r = (v) => Math.round(v * 1e7) / 1e7;
  return { latitudeDeg: r(lngLat.lat), longitudeDeg: r(lngLat.lng) };
}

export function isPos(p) {
  return p && typeof p.latitudeDeg === 'number' && typeof p.longitudeDeg === 'number' && isFinite(p.latitudeDeg) && isFinite(p.longitudeDeg);
}

/** A disc as a GeoJSON ring (48 sides). */
export function discRing(center, radiusM) {
  const ring = [];
  const lat = center.latitudeDeg, lon = center.longitudeDeg;
  const dLat = radiusM / 111320;
  const dLon = radiusM / (111320 * Math.max(0.01, Math.cos((lat * Math.PI) / 180)));
  for (let i = 0; i <= 48; i++) {
    const a = (i / 48) * 2 * Math.PI;
    ring.push([lon + dLon * Math.cos(a), lat + dLat * Math.sin(a)]);
  }
  return ring;
}

/** The world square of half-width `extentM` around the origin, as a ring. */
export function worldSquare(origin, extentM) {
  const dLat = extentM / 111320;
  const dLon = extentM / (111320 * Math.max(0.01, Math.cos((origin.latitudeDeg * Math.PI) / 180)));
  const { latitudeDeg: la, longitudeDeg: lo } = origin;
  return [[lo - dLon, la - dLat], [lo + dLon, la - dLat], [lo + dLon, la + dLat], [lo - dLon, la + dLat], [lo - dLon, la - dLat]];
}

export function centroid(points) {
  let la = 0, lo = 0, n = 0;
  for (const p of points) if (isPos(p)) { la += p.latitudeDeg; lo += p.longitudeDeg; n++; }
  return n ? { latitudeDeg: la / n, longitudeDeg: lo / n } : null;
}

/** Where a group's drones start, for drawing: points and discs. */
export function groupHomes(group) {
  const homes = (group && group.homes) || {};
  const out = { points: [], discs: [] };
  if (Array.isArray(homes.explicit)) out.points = homes.explicit.filter(isPos);
  if (homes.randomInArea && isPos(homes.randomInArea.center)) out.discs.push(homes.randomInArea);
  if (Array.isArray(homes.areas)) out.discs.push(...homes.areas.filter((a) => a && isPos(a.center)));
  return out;
}

/** A representative home of a group (for its label and its mission's first leg). */
export function groupAnchor(group) {
  const { points, discs } = groupHomes(group);
  if (discs.length) return discs[0].center;
  return centroid(points);
}
