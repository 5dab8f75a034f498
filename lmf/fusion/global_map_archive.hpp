// An exact, versioned binary archive of a GlobalMap: everything that decides
// its future fusions, so a map read back continues BIT-IDENTICALLY to the one
// written (the fusion server's durable state).
//
// What is stored: the GlobalMapConfig; the GlobalState (entities with ids,
// kinds, locations, lengths, parents and offsets, the next id, the capacity of
// the covariance buffer and the lower triangle of P, diagonal included); every
// robot record (joined, next_seq, min_seq, frames still needed, local maps
// waiting in its queue, fused seqs, frame history); submaps, paired graph
// edges, sightings still pending, whether any robot has joined. Doubles are stored as their
// IEEE-754 bits, so nothing is rounded. The capacity is restored too, so P's
// columns sit at the same strides as before (Eigen's kernels then see the same
// memory layout).
//
// File layout: the frame of lmf/io/binary_archive.hpp, magic "LMFGMAP\0",
// version kGlobalMapArchiveVersion.
// The payload is a sequence of fixed-size fields and counted arrays in the
// order of write_global_map() (global_map_archive.cpp documents it field by
// field). A version this build does not know, a wrong magic, a short file, a
// checksum mismatch, a count that cannot fit in the remaining bytes or a map
// that breaks an invariant (offsets, parents, ids) throw ArchiveError; nothing
// half-read is ever returned.
//
// Pure and synchronous; thread-safe for distinct objects.
#pragma once

#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <stdexcept>
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "lmf/fusion/global_map.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/io/binary_archive.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"

namespace lmf::fusion {

// 2: GlobalMapConfig::local_map_covariance_scale. 3: robot footprints
// (GlobalMapConfig::footprint_radius_m and the recorded positions). 4: crossing
// segments (GlobalMapConfig::crossing_*, FusionReport::crossing_segments_removed).
// 5: the map's transient "resolving sightings" flag is no longer stored (it
// was always false between calls; GlobalMap no longer has one). 6: frame
// registration (GlobalMapConfig::registration; FusionReport's registration
// outcome, offset, distance and score; PhaseTimes::registration_s). 8: place
// recognition (GlobalMapConfig::place_recognition). Older
// versions are refused by name ("older version"), never read with this layout:
// a server that finds one starts from its next good snapshot or from empty.
inline constexpr std::uint32_t kGlobalMapArchiveVersion = 8;

// The binary archive primitives (lmf/io/binary_archive.hpp), under the names
// the map's archive has always used.
using io::ArchiveError;
using io::ArchiveReader;
using io::ArchiveWriter;
using io::read_framed;
using io::write_framed;

// The whole map as a framed archive (magic "LMFGMAP\0").
void write_archive(const GlobalMap& map, std::ostream& out);
GlobalMap read_archive(std::istream& in);

// The map's payload only, to embed it in another archive (the server's state
// snapshot). read_global_map() checks the map's invariants.
void write_global_map(ArchiveWriter& w, const GlobalMap& map);
GlobalMap read_global_map(ArchiveReader& r);

// Pieces the server archives next to the map.
void write_local_map(ArchiveWriter& w, const LocalMapSnapshot& s);
LocalMapSnapshot read_local_map(ArchiveReader& r);
void write_fusion_report(ArchiveWriter& w, const FusionReport& report);
FusionReport read_fusion_report(ArchiveReader& r);
void write_sighting(ArchiveWriter& w, const RobotSighting& s);
RobotSighting read_sighting(ArchiveReader& r);

// Field-by-field bitwise equality (a restored map must be configured exactly
// like the one the caller would build).
bool same_config(const GlobalMapConfig& a, const GlobalMapConfig& b);

// Grants the archive functions access to GlobalMap's and GlobalState's
// private members (named as a friend there); defined in the .cpp only.
class GlobalMapArchive;

}  // namespace lmf::fusion
