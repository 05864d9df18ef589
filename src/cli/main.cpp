#include <cstdio>

int main()
{
    std::puts("posthaste: under construction");
    return 0;
}
