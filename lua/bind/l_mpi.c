/* lua/bind/l_mpi.c - cdvr.mpi: the process group of an `mpirun -np N cdvr script.lua` run
 * (cdvr/dist.h). In a build without MPI, or a run not started by mpirun, rank() is 0, size()
 * 1 and barrier() does nothing, so scripts run unchanged on one machine. */
#include "cdvr/dist.h"
#include "lcdvr.h"

static int l_rank(lua_State *L)
{
    lua_pushinteger(L, cdvr_dist_rank());
    return 1;
}

static int l_size(lua_State *L)
{
    lua_pushinteger(L, cdvr_dist_size());
    return 1;
}

static int l_barrier(lua_State *L)
{
    (void)L;
    cdvr_dist_barrier();
    return 0;
}

static const luaL_Reg mpi_funcs[] = {
    {"rank", l_rank}, {"size", l_size}, {"barrier", l_barrier}, {NULL, NULL}};

int lcdvr_open_mpi(lua_State *L)
{
    luaL_newlib(L, mpi_funcs);                    /* cdvr, mpi */
    lua_pushboolean(L, cdvr_dist_built());
    lua_setfield(L, -2, "built");
    lcdvr_name_table(L, -1, "cdvr.mpi");
    lua_setfield(L, -2, "mpi");                   /* cdvr */
    lcdvr_help_add(L, "cdvr.mpi.rank()", "this process's rank in an mpirun run (0 .. size-1; 0 without MPI)");
    lcdvr_help_add(L, "cdvr.mpi.size()", "number of processes of the run (1 without MPI)");
    lcdvr_help_add(L, "cdvr.mpi.barrier()", "wait until every process gets here (nothing in one process); a rank "
                   "waiting longer than CDVR_MPI_TIMEOUT seconds (default 1800) reports itself and ends the run");
    lcdvr_help_add(L, "cdvr.mpi.built", "true when this cdvr was built with MPI and IceT (-DCDVR_WITH_MPI=ON)");
    return 0;
}
