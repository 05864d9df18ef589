// The program that links one floor, whole, against only the floors it names (cmake/Floors.cmake):
// linking it is the check; it is never run.
int main()
{
    return 0;
}
