// `optinav map build` from many rasters and as a Slurm job array: the orthophoto inputs
// (--ortho A.tif [--ortho B.tif ...], --ortho-list FILES.txt, a GDAL VRT, /vsi* paths) resolved
// to one raster (a VRT mosaic when there are several), and the plan of a sharded build
// (`--plan slurm`: one task per shard, `map merge` after; app/slurm_plan.h, docs/MAPDB.md).
#pragma once

#include <string>
#include <vector>

#include "optinav/app/slurm_plan.h"
#include "optinav/maploc/map_db.h"

namespace optinav::app {

// The rasters listed in a file, one per line (blank lines and '#' comments skipped; a relative
// path is relative to the list's folder; /vsi* paths as they are). Throws Error naming the file
// (and the line of a bad entry) when it cannot be read or lists nothing.
std::vector<std::string> ReadOrthoList(const std::string& list_path);

// The raster `map build` reads: the one input as given, or, for several (the --ortho values,
// then the list's), a VRT mosaic written to `mosaic_path` (geo::WriteMosaicVrt: one CRS, read by
// window). Throws Error (field "--ortho") when there is none.
std::string ResolveOrthoInputs(const std::vector<std::string>& orthos,
                               const std::string& ortho_list, const std::string& mosaic_path);

struct MapBuildPlanOptions {
  std::vector<std::string> orthos;  // --ortho values
  std::string ortho_list;           // --ortho-list
  std::string out;                  // the merged map
  std::string plan_dir;             // "": OUT.slurm
  int shards = 0;                   // 0: derived (about 20 min of work per task, at most 1000)
  std::string slurm_args;
  maploc::MapBuildOptions build;
};

// Per task: CPUs = build threads; memory from the shard's tiles and features and GDAL's cache;
// time from the measured per-tile cost (docs/SLURM.md).
SlurmResources MapBuildTaskResources(const maploc::MapDatabase& grid, int shards);
// The shards for a grid: enough that a task has about 20 min of work, 1 - 1000.
int DefaultMapShards(const maploc::MapDatabase& grid);

// Writes the plan of a sharded build into plan_dir (the mosaic there too when there are several
// rasters): task I runs `optinav map build ... --shard I/N --out DIR/parts/part_I.db`, the merge
// `optinav map merge --plan-dir DIR --out OUT`. Throws Error on bad inputs.
SlurmPlan WriteMapBuildPlan(const MapBuildPlanOptions& options);

// The parts of the plan in plan_dir (its tasks' outputs) after checking that every task has
// finished (ThrowIfUnfinished).
std::vector<std::string> PlannedMapParts(const std::string& plan_dir);

}  // namespace optinav::app
