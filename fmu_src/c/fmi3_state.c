/* featherstar FMI 3.0 shell: FMU state snapshots (get, set, free) for ME and CS alike.
 *
 * CasADi keeps everything an instance computes in one flat struct, so a snapshot is a copy of
 * that struct plus what the shell adds (mode, time, tolerances, the integrator's step, its
 * controller memory and FSAL derivative): restoring it makes the next doStep bit-identical to
 * the one taken after the snapshot, which is what a master's step rejection relies on.
 */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "fmi3_shell.h"

typedef struct {
  const fs_instance* owner;
  fs_dynamic dyn;
} fs_snapshot;

static size_t snapshot_size(const fs_instance* s) {
  return sizeof(fs_snapshot) + s->model->n_x * sizeof(double) + s->model->memory_size;
}

FMI3_Export fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState* FMUState) {
  fs_instance* s = fs_check(instance, "fmi3GetFMUState", FS_ANY_MODE, FS_ANY_KIND);
  fs_snapshot* snap;
  unsigned char* bytes;
  if (!s) return fmi3Error;
  if (!FMUState) {
    fs_error(s, "fmi3GetFMUState: NULL FMUState");
    return fmi3Error;
  }
  snap = (fs_snapshot*)*FMUState;
  if (snap && snap->owner != s) {
    fs_error(s, "fmi3GetFMUState: *FMUState belongs to another instance");
    return fmi3Error;
  }
  /* The spec lets an importer pass back an existing state to be overwritten in place. */
  if (!snap) snap = malloc(snapshot_size(s));
  if (!snap) {
    fs_error(s, "fmi3GetFMUState: out of memory");
    return fmi3Error;
  }
  snap->owner = s;
  snap->dyn = s->dyn;
  bytes = (unsigned char*)(snap + 1);
  memcpy(bytes, s->work, s->model->n_x * sizeof(double));
  memcpy(bytes + s->model->n_x * sizeof(double), s->memory, s->model->memory_size);
  *FMUState = snap;
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
  fs_instance* s = fs_check(instance, "fmi3SetFMUState", FS_ANY_MODE, FS_ANY_KIND);
  const fs_snapshot* snap = (const fs_snapshot*)FMUState;
  const unsigned char* bytes;
  if (!s) return fmi3Error;
  /* CasADi's memory holds pointers into itself, so it may only go back where it came from. */
  if (!snap || snap->owner != s) {
    fs_error(s, "fmi3SetFMUState: %s", snap ? "FMUState belongs to another instance" : "NULL FMUState");
    return fmi3Error;
  }
  s->dyn = snap->dyn;
  bytes = (const unsigned char*)(snap + 1);
  memcpy(s->work, bytes, s->model->n_x * sizeof(double));
  memcpy(s->memory, bytes + s->model->n_x * sizeof(double), s->model->memory_size);
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState* FMUState) {
  fs_instance* s = fs_check(instance, "fmi3FreeFMUState", FS_ANY_MODE, FS_ANY_KIND);
  if (!s) return fmi3Error;
  if (!FMUState || !*FMUState) return fmi3OK;
  if (((fs_snapshot*)*FMUState)->owner != s) {
    fs_error(s, "fmi3FreeFMUState: FMUState belongs to another instance");
    return fmi3Error;
  }
  free(*FMUState);
  *FMUState = NULL;
  return fmi3OK;
}
