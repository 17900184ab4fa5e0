/* The FMI 2.0 co-simulation functions as a table of pointers, and its lookup in a loaded binary:
 * used where one binary forwards to another (fmi_shim.c to pythonfmu's binary or to the worker client,
 * fmi_worker.c to pythonfmu's binary). */
#ifndef WINGSIM_FMI2_TABLE_H
#define WINGSIM_FMI2_TABLE_H

#include <stddef.h>

#include "fmi2Functions.h"
#include "native_platform.h"

#define FMI2_CO_SIMULATION_FUNCTIONS(X)                                                            \
    X(SetDebugLogging) X(Instantiate) X(FreeInstance) X(SetupExperiment) X(EnterInitializationMode) \
    X(ExitInitializationMode) X(Terminate) X(Reset) X(GetReal) X(GetInteger) X(GetBoolean)         \
    X(GetString) X(SetReal) X(SetInteger) X(SetBoolean) X(SetString) X(GetFMUstate) X(SetFMUstate) \
    X(FreeFMUstate) X(SerializedFMUstateSize) X(SerializeFMUstate) X(DeSerializeFMUstate)          \
    X(GetDirectionalDerivative) X(SetRealInputDerivatives) X(GetRealOutputDerivatives) X(DoStep)    \
    X(CancelStep) X(GetStatus) X(GetRealStatus) X(GetIntegerStatus) X(GetBooleanStatus)           \
    X(GetStringStatus)

typedef struct {
#define FMI2_TABLE_FIELD(name) fmi2##name##TYPE *name;
    FMI2_CO_SIMULATION_FUNCTIONS(FMI2_TABLE_FIELD)
#undef FMI2_TABLE_FIELD
} Fmi2Table;

/* Fill `table` from the binary `handle` (library_open); NULL, or the name of the first function missing. */
__attribute__((unused)) static const char *fmi2_table_resolve(void *handle, Fmi2Table *table)
{
#define FMI2_TABLE_RESOLVE(name)                                                                   \
    if ((table->name = (fmi2##name##TYPE *)library_symbol(handle, "fmi2" #name)) == NULL) return "fmi2" #name;
    FMI2_CO_SIMULATION_FUNCTIONS(FMI2_TABLE_RESOLVE)
#undef FMI2_TABLE_RESOLVE
    return NULL;
}

#endif
