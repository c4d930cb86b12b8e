// Map databases as whole files (mutated SQLite pages): loading (schema, metadata, checksums,
// blobs) and the full check (PRAGMA integrity_check + every checksum) must refuse damage with an
// Error, never crash or accept a changed blob.
#include "fuzz/fuzz_target.h"
#include "optinav/maploc/map_db.h"

using namespace optinav;

OPTINAV_FUZZ_TARGET(map_db_file) {
  fuzz::QuietLibraries();
  const std::string path = fuzz::WriteScratch("map_file.db", data, size);
  try {
    maploc::LoadMapDatabase(path);
  } catch (const Error&) {
  }
  try {
    maploc::CheckMapDatabase(path);
  } catch (const Error&) {
  }
  return 0;
}
