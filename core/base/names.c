/* core/base/names.c - the registry name rule (cdvr/names.h). */
#include "cdvr/names.h"

#include <string.h>

int cdvr_name_valid(const char *name, size_t size)
{
    size_t n = name ? strnlen(name, size) : 0;
    if (n == 0 || n >= size)
        return 0;
    for (size_t i = 0; i < n; i++)
        if (!((name[i] >= 'a' && name[i] <= 'z') || (name[i] >= '0' && name[i] <= '9') ||
              name[i] == '_'))
            return 0;
    return 1;
}
