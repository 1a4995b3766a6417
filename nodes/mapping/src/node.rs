//! The mapping node (`rover mapping`): terrain scans in; the map, its image, statistics and the
//! located rocks out.
