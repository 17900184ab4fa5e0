"""Export stage: the built FMUs handed on as one coupled system.

- ``system``     the built FMUs as one coupled system (components, connections, public variables)
- ``ssp``        that system as an SSP 1.0 package (``wingsim export``)
- ``container``  that system as one FMU, ``wing.fmu`` (our container binary, ``container.c``)
- ``validate``   ``wingsim validate``: built FMUs checked as another FMI tool would
"""
