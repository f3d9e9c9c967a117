"""The plant's physical constants of air and of the paper's bench, typed here (not taken from
the model): the heat capacity ratio, the atmosphere and the supply of the paper's flow map."""

#: Heat capacity ratio of air [-].
GAMMA_AIR = 1.4
#: Atmospheric pressure [Pa, absolute].
P_ATM = 1.0e5
#: The supply pressure at which the paper identified Eq. 8: 10 bar [Pa, absolute].
P_SUPPLY = 1.0e6
