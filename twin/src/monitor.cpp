#include "maglead/twin/monitor.hpp"
